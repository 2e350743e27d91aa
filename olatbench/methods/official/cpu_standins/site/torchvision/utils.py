"""Stand-in for torchvision.utils (olatbench.methods.official.cpu_standins.save_image)."""

from olatbench.methods.official.cpu_standins.save_image import make_grid, save_image

__all__ = ["make_grid", "save_image"]
