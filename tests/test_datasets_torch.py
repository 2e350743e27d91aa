"""The optional torch adapter."""

from __future__ import annotations

import numpy as np
import pytest
from datasets_trees import write_nrhints_tree

from olatbench.datasets import load_scene

torch = pytest.importorskip("torch")


def test_frame_dataset_items(tmp_path):
    from olatbench.datasets.torch_adapter import FrameDataset

    write_nrhints_tree(tmp_path / "s", size=(16, 12))
    frames = load_scene(tmp_path / "s").split("train")
    data = FrameDataset(frames, colourspace="linear", resolution=(8, 6))
    item = data[1]
    assert len(data) == 4 and item["frame_id"] == "001"
    assert (
        item["image"].shape == (6, 8, 3)
        and item["alpha"].shape == (6, 8)
        and item["image"].dtype == torch.float32
    )
    np.testing.assert_allclose(item["K"].numpy(), frames[1].camera.resized(8, 6).K, rtol=1e-6)
    np.testing.assert_allclose((item["w2c"] @ item["c2w"]).numpy(), np.eye(4), atol=1e-5)
    np.testing.assert_allclose(item["light_pos"].numpy(), frames[1].light.position, rtol=1e-6)
