"""Use olatbench's loaders from another project with numpy alone (no torch is imported).

python examples/loaders_numpy.py path/to/scene
"""

from __future__ import annotations

import sys

import numpy as np

from olatbench.datasets import load_scene


def main(root: str) -> None:
    scene = load_scene(root)  # NRHints, GS³ or SSS-GS, detected from the files
    print(f"{scene.name}: {scene.format}, splits {scene.splits}")
    for frame in scene.split("train")[:3]:
        # float32 (H, W, 3), composited on the official background
        image = frame.load(colourspace="linear")
        distance = np.linalg.norm(frame.light.position - frame.camera.position)
        print(
            f"  {frame.frame_id}: {image.rgb.shape}, mean linear radiance {image.rgb.mean():.4f}, "
            f"light {distance:.3f} units from the camera, fx {frame.camera.fx:.1f} px"
        )
    assert "torch" not in sys.modules


if __name__ == "__main__":
    main(sys.argv[1])
