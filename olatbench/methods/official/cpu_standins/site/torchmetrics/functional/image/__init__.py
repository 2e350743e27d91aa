"""Stand-in for torchmetrics.functional.image
(olatbench.methods.official.cpu_standins.torchmetrics_image)."""

from olatbench.methods.official.cpu_standins.torchmetrics_image import (
    learned_perceptual_image_patch_similarity,
    peak_signal_noise_ratio,
    structural_similarity_index_measure,
)

__all__ = [
    "learned_perceptual_image_patch_similarity",
    "peak_signal_noise_ratio",
    "structural_similarity_index_measure",
]
