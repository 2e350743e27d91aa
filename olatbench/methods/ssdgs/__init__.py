"""SSD-GS, the reference method: see `olatbench.methods.ssdgs.method.SSDGS` and docs/ssdgs.md."""

from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.method import SSDGS
from olatbench.methods.ssdgs.presets import PRESETS, resolve_presets

__all__ = ["PRESETS", "SSDGS", "SSDGSConfig", "resolve_presets"]
