"""``simple_knn._C.distCUDA2`` on the CPU: olatbench's exact nearest-neighbour search.

``distCUDA2(points [N, 3])`` returns [N]: each point's mean squared distance to its 3 nearest other
points, which the authors' ``create_from_pcd`` turns into the initial scales. simple-knn's CUDA
kernel searches Morton-ordered boxes and may miss a true neighbour; this returns the exact value
(`olatbench.gaussians.knn.mean_neighbour_sq_distance`).
"""

from __future__ import annotations

import torch

from olatbench.gaussians.knn import mean_neighbour_sq_distance


def distCUDA2(points: torch.Tensor) -> torch.Tensor:
    """[N] mean squared distance of each of ``points`` [N, 3] to its 3 nearest other points
    (float32)."""
    return mean_neighbour_sq_distance(points.float(), k=3)
