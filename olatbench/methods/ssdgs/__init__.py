"""SSD-GS, the reference method: see `olatbench.methods.ssdgs.method.SSDGS` and docs/ssdgs.md.

The package imports lazily (PEP 562): ``from olatbench.methods.ssdgs import SSDGS`` loads torch, but
its torch-free modules (``spec``, ``config``, ``presets``) can be imported without it.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "SSDGS": "olatbench.methods.ssdgs.method",
    "SSDGSConfig": "olatbench.methods.ssdgs.config",
    "PRESETS": "olatbench.methods.ssdgs.presets",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'olatbench.methods.ssdgs' has no attribute {name!r}")
    return getattr(importlib.import_module(_EXPORTS[name]), name)
