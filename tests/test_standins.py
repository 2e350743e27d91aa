"""Paper-scale stand-ins: the suite's format and image size, the requested counts, rendered once."""

from __future__ import annotations

import pytest

pytest.importorskip("mitsuba")

from olatbench.datasets import load_scene
from olatbench.datasets.synth.standins import STANDINS, ensure_standin


def test_standin_has_the_suites_format_size_and_counts(tmp_path):
    folder = ensure_standin("sssgs", train=2, root=tmp_path, progress=False)
    scene = load_scene(folder)
    assert scene.format == STANDINS["sssgs"].format == "sssgs"
    train, test = scene.split("train"), scene.split("test")
    assert len(train) == 2 and len(test) == 2  # 500/500 scaled to 2 training images
    camera = train[0].camera
    assert (camera.width, camera.height) == (256, 256)
    mtime = (folder / "synth.json").stat().st_mtime_ns
    # reused, not re-rendered
    assert ensure_standin("sssgs", train=2, root=tmp_path, progress=False) == folder
    assert (folder / "synth.json").stat().st_mtime_ns == mtime
    assert not list(tmp_path.glob(".*partial"))


def test_unknown_suite_is_one_clear_error(tmp_path):
    with pytest.raises(
        KeyError, match="no stand-in for suite 'mini'; stand-ins: nrhints, gs3, sssgs"
    ):
        ensure_standin("mini", root=tmp_path)
