"""Job ids: stable for the same inputs, sensitive to every input that decides a result."""

from __future__ import annotations

import dataclasses
import importlib
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import test_runner_support as support

from olatbench.bench.jobs import code_hash, data_manifest_hash
from olatbench.bench.plan import PlanOptions, make_plan
from olatbench.datasets.images import read_image, write_image


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


def plan(data, out, **kwargs):
    suite = kwargs.pop("suite", support.tiny_suite())
    return make_plan("trivial", suite, out, data_root=data, progress=False, **kwargs)


def ids(jobs):
    return [job.id for job in jobs]


def test_ids_are_stable_and_ignore_location_device_and_cadence(data, tmp_path):
    first = plan(data, tmp_path / "runs")
    assert len(first) == 2 and all(len(job.id) == 16 for job in first)
    assert len(set(ids(first))) == 2
    copy = tmp_path / "elsewhere" / "copy"
    shutil.copytree(data, copy)  # new paths and mtimes, same bytes
    options = PlanOptions(
        device="meta", checkpoint_every=3, keep_checkpoints=5, save_components=True
    )
    second = plan(copy, tmp_path / "other-runs", options=options)
    assert ids(second) == ids(first)


def test_ids_are_stable_across_processes(data, tmp_path):
    script = (
        f"import sys; sys.path.insert(0, {str(support.TESTS)!r}); import test_runner_support as s; "
        "from olatbench.bench.plan import make_plan; print(' '.join(j.id for j in "
        f"make_plan('trivial', s.tiny_suite(), 'x', data_root={str(data)!r}, progress=False)))"
    )
    env = {**os.environ, "PYTHONHASHSEED": "123"}
    output = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, check=True
    )
    assert output.stdout.split() == ids(plan(data, tmp_path / "runs"))


def test_ids_change_with_every_result_deciding_input(data, tmp_path):
    base = plan(data, tmp_path / "runs")[0]
    variants = {
        "seed": plan(data, tmp_path / "runs", seeds=2)[1],
        "variant config": plan(data, tmp_path / "runs", variants=["ablation-B"])[0],
        "iterations": plan(data, tmp_path / "runs", iterations=7)[0],
        "resolution": plan(data, tmp_path / "runs", resolution=(32, 24))[0],
        "protocol": plan(
            data, tmp_path / "runs", suite=support.tiny_suite(protocol="olatbench-v1")
        )[0],
        "colourspace": dataclasses.replace(base, colourspace="linear").with_id(),
        "protocol version": dataclasses.replace(base, protocol_version=2).with_id(),
        "code": dataclasses.replace(base, code="0" * 64).with_id(),
    }
    for name, job in variants.items():
        assert job.id != base.id, name
    assert variants["seed"].scene == base.scene and variants["seed"].seed == 1

    image = data / "Alpha" / "train" / "001.png"
    pixels = read_image(image)
    pixels[3, 5, 0] = 1.0 - pixels[3, 5, 0]  # one pixel of one training image
    write_image(image, pixels, "uint8")
    changed = plan(data, tmp_path / "runs")
    assert changed[0].id != base.id
    assert changed[1].id == plan(data, tmp_path / "runs")[1].id  # the other scene is untouched


def test_manifest_cache_matches_a_fresh_hash_and_sees_same_size_edits(data, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    scene = data / "Beta"
    cached = data_manifest_hash(scene)
    assert data_manifest_hash(scene) == cached == data_manifest_hash(scene, use_cache=False)
    metadata = scene / "transforms_train.json"
    text = metadata.read_text()
    metadata.write_text(text.replace("1", "2", 1))  # same size, new content
    assert len(metadata.read_text()) == len(text)
    assert data_manifest_hash(scene) != cached
    metadata.write_text(text)
    assert data_manifest_hash(scene) == cached
    (scene / "notes.txt").write_text("extra file")
    assert data_manifest_hash(scene) != cached
    (scene / "notes.txt").unlink()
    (scene / ".DS_Store").write_bytes(b"hidden files are ignored")
    assert data_manifest_hash(scene) == cached
    # ground truth under new illumination, installed later
    (scene / "novel_lights" / "studio").mkdir(parents=True)
    (scene / "novel_lights" / "studio" / "r_0000.exr").write_bytes(
        b"not read by training or the test split"
    )
    assert data_manifest_hash(scene) == cached


def test_code_hash_follows_the_method_source(tmp_path, monkeypatch):
    module = tmp_path / "my_method_module.py"
    source = (
        "from test_runner_support import TrivialMethod\n"
        "class MyMethod(TrivialMethod):\n    name = 'mine'\n"
    )
    module.write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    loaded = importlib.import_module("my_method_module")
    before = code_hash(loaded.MyMethod)
    assert code_hash(loaded.MyMethod) == before
    module.write_text(source + "# a change\n")
    assert code_hash(loaded.MyMethod) != before
    assert code_hash(loaded.MyMethod) != code_hash(support.TrivialMethod)


def test_manifest_of_a_missing_folder_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="scene folder not found"):
        data_manifest_hash(tmp_path / "nothing")


def test_data_hash_reads_pixels_not_only_sizes(data):
    image = data / "Alpha" / "test" / "000.png"
    before = data_manifest_hash(data / "Alpha", use_cache=False)
    pixels = read_image(image)
    write_image(image, np.flip(pixels, axis=1).copy(), "uint8")
    assert data_manifest_hash(data / "Alpha", use_cache=False) != before
