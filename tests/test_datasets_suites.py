"""Suites: the paper's scene lists, settings, aliases and folder lookup."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from olatbench.datasets import DatasetError
from olatbench.datasets.suites import canonical_scene_name, get_suite, suite_names

CSV_CANDIDATES = [
    Path(__file__).parents[1] / "olatbench/reports/data/ssdgs_iclr2026.csv",
    Path("/work/shared/published/ssdgs_iclr2026.csv"),
]


def test_suite_settings_follow_the_paper():
    assert suite_names() == ["nrhints", "gs3", "sssgs", "mini"]
    nrhints, gs3, sssgs = get_suite("nrhints"), get_suite("gs3"), get_suite("sssgs")
    assert (len(nrhints.scenes), nrhints.resolution, nrhints.iterations) == (7, None, 100_000)
    assert (len(gs3.scenes), gs3.resolution, gs3.iterations) == (6, (512, 512), 100_000)
    assert (len(sssgs.scenes), sssgs.resolution, sssgs.iterations) == (5, (256, 256), 60_000)
    assert {s.protocol for s in (nrhints, gs3, sssgs)} == {"ssdgs"}


def test_mini_suite_is_generated():
    mini = get_suite("mini")
    assert mini.scenes == ("diffuse_shadow", "aniso_metal", "translucent")
    assert (mini.format, mini.generator, mini.iterations, mini.protocol, mini.resolution) == (
        "nrhints",
        "olatbench.datasets.synth.mini:ensure_mini_suite",
        3000,
        "olatbench-v1",
        None,
    )


def test_scene_lists_match_the_published_csv():
    path = next((p for p in CSV_CANDIDATES if p.is_file()), None)
    if path is None:
        pytest.skip("published CSV not available")
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    for name in ("nrhints", "gs3", "sssgs"):
        published = {row["scene"] for row in rows if row["suite"] == name} - {"Average"}
        assert published == set(get_suite(name).scenes), name


def test_aliases_and_scene_path(tmp_path):
    assert canonical_scene_name("Cat_on_Decor") == "CatSmall"
    assert canonical_scene_name("bunny_small", "sssgs") == "Bunny"
    assert canonical_scene_name("aniso_metal", "gs3") == "AnisoMetal"
    assert canonical_scene_name("unknown") == "unknown"
    (tmp_path / "Cluttered").mkdir()
    assert get_suite("nrhints").scene_path(tmp_path, "FurScene") == tmp_path / "Cluttered"
    assert get_suite("nrhints").scene_path(tmp_path, "Cluttered") == tmp_path / "Cluttered"
    with pytest.raises(DatasetError, match="looked for folders Pixiu, pixiu"):
        get_suite("nrhints").scene_path(tmp_path, "Pixiu")
    with pytest.raises(DatasetError, match="has no scene 'Lego'"):
        get_suite("nrhints").scene_path(tmp_path, "Lego")
    with pytest.raises(DatasetError, match="known suites"):
        get_suite("blender")
