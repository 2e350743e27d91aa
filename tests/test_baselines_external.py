"""The external-method adapter, exercised with stand-in scripts that behave like official train/render scripts."""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from datasets_trees import write_nrhints_tree

from olatbench.datasets import load_scene
from olatbench.datasets.images import read_image
from olatbench.methods.baselines.external import (
    ExternalRunError,
    export_renders,
    plan_external,
    run_external,
)
from olatbench.methods.baselines.external_specs import SPECS, UNVERIFIED, ExternalSpec, get_spec

# A stand-in "official" script: reads the converted scene's transforms_test.json in file order and writes
# <model>/test/ours_<it>/renders/<index:05d>.png whose red channel encodes that frame's light x position.
STANDIN = textwrap.dedent("""
    import argparse, json, sys
    from pathlib import Path
    import numpy as np
    from olatbench.datasets.images import write_image
    parser = argparse.ArgumentParser()
    parser.add_argument("-s"); parser.add_argument("-m"); parser.add_argument("--iterations", type=int)
    parser.add_argument("--white_background", action="store_true"); parser.add_argument("--only", type=int)
    parser.add_argument("--fail", action="store_true")
    args = parser.parse_args()
    if args.fail:
        for i in range(40):
            print(f"training line {i}")
        print("RuntimeError: CUDA out of memory", file=sys.stderr)
        sys.exit(3)
    frames = json.loads((Path(args.s) / "transforms_test.json").read_text())["frames"]
    out = Path(args.m) / "test" / f"ours_{args.iterations}" / "renders"
    for index, frame in enumerate(frames[: args.only]):
        value = (frame["pl_pos"][0] + 10.0) / 20.0
        write_image(out / f"{index:05d}.png", np.full((4, 4, 3), value, np.float32), "uint8")
    print("white" if args.white_background else "black")
""")


def standin_spec(*extra: str) -> ExternalSpec:
    return ExternalSpec(
        name="standin", paper="test", repository="https://example.invalid/standin", commit=UNVERIFIED,
        data_format="nrhints",
        commands=(("train", ("{python}", "standin.py", "-s", "{scene}", "-m", "{model}", "--iterations",
                             "{iterations}", "{*suite_args}", *extra)),),
        renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
        suite_args={"gs3": {"train": ("--white_background",)}})


@pytest.fixture()
def setup(tmp_path: Path):
    tree = write_nrhints_tree(tmp_path / "Cat", n_train=2, n_test=4, size=(8, 6), seed=4)
    checkout = tmp_path / "checkout"
    checkout.mkdir()
    (checkout / "standin.py").write_text(STANDIN)
    return tree, checkout, tmp_path / "work"


def test_renders_map_back_to_frame_ids(setup) -> None:
    tree, checkout, work = setup
    renders = run_external(standin_spec(), tree.root, work, checkout, suite="gs3", iterations=7)
    source = load_scene(tree.root)
    assert list(renders) == [f.frame_id for f in source.split("test")]
    for frame in source.split("test"):
        value = read_image(renders[frame.frame_id])[0, 0, 0]
        assert value == pytest.approx((frame.light.position[0] + 10.0) / 20.0, abs=1 / 255)
    assert (work / "logs" / "train.log").read_text().strip().endswith("white")  # suite args expanded
    assert json.loads((work / "scene" / "transforms_test.json").read_text())["frames"]  # converted scene

    copies = export_renders(renders, work / "run" / "renders" / "test")
    assert sorted(p.name for p in copies.values()) == sorted(f"{f.frame_id}.png" for f in source.split("test"))
    assert all(np.array_equal(read_image(copies[k]), read_image(v)) for k, v in renders.items())


def test_a_failing_command_reports_its_command_line_and_log_tail(setup) -> None:
    tree, checkout, work = setup
    with pytest.raises(ExternalRunError) as error:
        run_external(standin_spec("--fail"), tree.root, work, checkout, iterations=7)
    message = str(error.value)
    assert "exit code 3" in message and "standin.py" in message and "--fail" in message
    assert "CUDA out of memory" in message and "training line 39" in message
    assert "training line 5\n" not in message  # only the tail
    assert str(work / "logs" / "train.log") in message


def test_missing_renders_are_listed(setup) -> None:
    tree, checkout, work = setup
    with pytest.raises(ExternalRunError, match=r"3 of 4 renders are missing") as error:
        run_external(standin_spec("--only", "1"), tree.root, work, checkout, iterations=7)
    assert "00001.png" in str(error.value) and "holds: 00000.png" in str(error.value)


def test_bad_checkout_executable_and_placeholders(setup, tmp_path: Path) -> None:
    tree, checkout, work = setup
    with pytest.raises(ExternalRunError, match="no checkout"):
        run_external(standin_spec(), tree.root, work, tmp_path / "nowhere", iterations=7)
    with pytest.raises(ExternalRunError, match="cannot start"):
        run_external(standin_spec(), tree.root, work, checkout, iterations=7, python=str(tmp_path / "no-python"))
    with pytest.raises(ValueError, match="needs iterations"):
        plan_external(standin_spec(), tree.root, work, checkout)
    with pytest.raises(ValueError, match="unknown placeholder 'gpu'"):
        plan_external(standin_spec("--device={gpu}"), tree.root, work, checkout, iterations=7)


def test_official_specs_fill_in(setup) -> None:
    tree, checkout, work = setup
    assert set(SPECS) == {"gs3", "ssdgs", "rng", "gigs"}
    plan = plan_external(get_spec("gs3"), tree.root, work, checkout, suite="gs3", iterations=100_000,
                         python=sys.executable)
    train, render = (argv for _, argv in plan.commands)
    assert train[:2] == [sys.executable, "train.py"] and "--white_background" in train and "--hdr" in train
    assert "--gamma" in render and plan.colourspace == "gamma22"
    folder = plan.model_dir / "test" / "ours_100000" / "renders"
    assert [p.parent for p in plan.renders.values()] == [folder] * 4
    assert load_scene(plan.scene_dir).format == "gs3" and len(load_scene(plan.scene_dir).split("test")) == 4
    with pytest.raises(ValueError, match="commit"):
        ExternalSpec(name="x", paper="", repository="", commit="abc", data_format="nrhints",
                     commands=(("train", ("true",)),), renders="")
