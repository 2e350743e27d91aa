"""Value ranges of config fields, declared beside the fields and checked when a config is made.

A config dataclass lists its numeric fields' ranges in a class attribute ``ranges:
ClassVar[dict[str, Range]]``; a subclass adds to (or overrides) its bases' (`field_range` walks the
class hierarchy). `check_ranges` is called from the config's ``__post_init__``, so every way of
making a config (presets, ``--set``, a job.json) is checked; ``--set`` also checks each override on
its own (`olatbench.methods.overrides`), so the error names the option. ``None``
(an optional field left unset) is always in range; a tuple is in range when each of its items is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class Range:
    """``low ≤ value ≤ high`` (either bound None: unbounded; ``open_low`` / ``open_high``:
    strict)."""

    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False

    def contains(self, value: Any) -> bool:
        """Whether ``value`` (a number, a tuple of numbers or None) lies in the range; NaN never
        does."""
        if value is None:
            return True
        if isinstance(value, (tuple, list)):
            return all(self.contains(item) for item in value)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            return False
        if self.low is not None and (value <= self.low if self.open_low else value < self.low):
            return False
        return self.high is None or (value < self.high if self.open_high else value <= self.high)

    def describe(self) -> str:
        """The range as a message says it: ``> 0``, ``≥ 1``, ``in [0, 1]``, ``in (0, 1)``."""
        if self.low is not None and self.high is not None:
            return (
                f"in {'(' if self.open_low else '['}{_number(self.low)}, {_number(self.high)}"
                f"{')' if self.open_high else ']'}"
            )
        if self.low is not None:
            return f"{'>' if self.open_low else '≥'} {_number(self.low)}"
        if self.high is not None:
            return f"{'<' if self.open_high else '≤'} {_number(self.high)}"
        return "any number"


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else str(value)


POSITIVE = Range(0, open_low=True)
NON_NEGATIVE = Range(0)
AT_LEAST_ONE = Range(1)
UNIT = Range(0, 1)
OPEN_UNIT = Range(0, 1, open_low=True, open_high=True)
# a learning rate: 0 freezes the parameters; a negative rate would climb the loss
RATE = NON_NEGATIVE


def field_range(config_type: type, name: str) -> Range | None:
    """The declared range of field ``name`` of the config class (its own ``ranges`` or the nearest
    base's)."""
    for cls in config_type.__mro__:
        declared = vars(cls).get("ranges")
        if isinstance(declared, dict) and name in declared:
            return declared[name]
    return None


def check_ranges(config: Any, label: str) -> None:
    """A `ValueError` naming the first field of ``config`` whose value is outside its declared
    range."""
    for item in fields(config):
        allowed = field_range(type(config), item.name)
        value = getattr(config, item.name)
        if allowed is not None and not allowed.contains(value):
            raise ValueError(
                f"{label} config: {item.name} must be {allowed.describe()}, got {value!r}"
            )
