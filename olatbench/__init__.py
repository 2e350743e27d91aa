"""olatbench: benchmark relightable 3D reconstruction on OLAT (one-light-at-a-time) data.

Layers (each imports only those above it): ``datasets`` (numpy only) -> ``metrics`` -> ``gaussians``
-> ``methods`` -> ``bench`` -> ``reports``.
"""

__version__ = "0.1.0"  # the only place: pyproject.toml reads it (tool.setuptools.dynamic)
