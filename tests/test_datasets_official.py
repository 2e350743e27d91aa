"""Frame.load against the official ground truth of each pipeline (reproduced in official.py)."""

from __future__ import annotations

import numpy as np
import pytest
from datasets_trees import write_gs3_tree, write_nrhints_tree, write_sssgs_tree

from olatbench.datasets import DatasetError, load_scene
from olatbench.datasets.formats.gs3 import loader_image as gs3_ground_truth
from olatbench.datasets.formats.nrhints import official_ground_truth as nrhints_ground_truth
from olatbench.datasets.formats.sssgs import official_ground_truth as sssgs_ground_truth
from olatbench.datasets.official import official_ground_truth


def test_nrhints_ground_truth_is_the_truncated_black_composite(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[0]
    stored = tree.frames["train"][0]["stored"]
    # independent: the loader's arithmetic in float64, np.array(x * 255, dtype=np.byte) semantics
    expected = np.floor(stored[..., :3].astype(np.float64) * stored[..., 3:] * 255.0 + 1e-9) / 255.0
    np.testing.assert_allclose(nrhints_ground_truth(frame), expected, atol=1e-6)
    loaded = frame.load(colourspace="srgb").rgb
    assert np.max(np.abs(loaded - nrhints_ground_truth(frame))) < 1 / 255 + 1e-6


def test_gs3_ground_truth_with_and_without_the_alpha_quirk(tmp_path):
    tree = write_gs3_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[1]
    stored = tree.frames["train"][1]["stored"]
    premultiplied, alpha = stored[..., :3].astype(np.float64), stored[..., 3:]
    correct = np.clip((premultiplied + 1 - alpha) ** (1 / 2.2), 0, 1)
    quirk = np.clip((premultiplied * alpha + 1 - alpha) ** (1 / 2.2), 0, 1)
    np.testing.assert_allclose(gs3_ground_truth(frame, quantize=None), quirk, atol=1e-5)
    np.testing.assert_allclose(
        gs3_ground_truth(frame, alpha_quirk=False, quantize=None), correct, atol=1e-5
    )
    np.testing.assert_allclose(gs3_ground_truth(frame), np.rint(quirk * 255) / 255, atol=1e-6)
    # Frame.load composites correctly; it agrees with the quirk wherever alpha is 0 or 1
    loaded = np.clip(frame.load(colourspace="gamma22").rgb, 0, 1)
    np.testing.assert_allclose(loaded, correct, atol=1e-5)
    binary = (alpha[..., 0] == 0) | (alpha[..., 0] == 1)
    fractional = ~binary & (premultiplied.sum(axis=2) > 0.05)
    np.testing.assert_allclose(loaded[binary], quirk[binary], atol=1e-5)
    # the quirk multiplies by alpha twice: edge pixels come out darker (or equal once clipped to
    # white)
    darker = quirk[fractional].sum(-1) - loaded[fractional].sum(-1)
    assert fractional.any() and np.all(darker <= 1e-5) and np.any(darker < -0.01)


def test_sssgs_ground_truth_is_colour_times_mask(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[2]
    stored = tree.frames["train"][2]["stored"]
    np.testing.assert_allclose(
        sssgs_ground_truth(frame), stored[..., :3] * stored[..., 3:], atol=1e-6
    )
    np.testing.assert_allclose(
        frame.load(colourspace="srgb").rgb, sssgs_ground_truth(frame), atol=1e-6
    )


def test_dispatch_and_path_frames(tmp_path):
    write_nrhints_tree(tmp_path / "s", n_path=1)
    scene = load_scene(tmp_path / "s")
    frame = scene.split("test")[0]
    np.testing.assert_array_equal(
        official_ground_truth(frame, "nrhints"), nrhints_ground_truth(frame)
    )
    with pytest.raises(DatasetError, match="no official ground truth"):
        official_ground_truth(frame, "colmap")
    with pytest.raises(DatasetError, match="no image"):
        nrhints_ground_truth(scene.split("path")[0])
