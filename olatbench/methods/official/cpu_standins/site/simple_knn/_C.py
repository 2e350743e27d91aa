"""Stand-in for simple_knn._C (olatbench.methods.official.cpu_standins.knn)."""

from olatbench.methods.official.cpu_standins.knn import distCUDA2

__all__ = ["distCUDA2"]
