"""Methods: the `Method` interface, the registry, SSD-GS and the baselines."""

from olatbench.methods.base import Method, Views
from olatbench.methods.registry import get_method, method_names, register

__all__ = ["Method", "Views", "get_method", "method_names", "register"]
