"""Image sizes written as text: the one parser every option and file reading a size calls."""

from __future__ import annotations


def parse_size(text: str) -> tuple[int, int]:
    """``"N"`` (N × N) or ``"WxH"`` (``x`` or ``X``, spaces around the text ignored) as (width, height) in pixels;
    a `ValueError` saying the accepted forms otherwise. Callers check their own minimum."""
    width, separator, height = str(text).strip().lower().partition("x")
    try:
        return int(width), int(height if separator else width)  # "256x" has an empty height: refused
    except ValueError:
        raise ValueError(f"expected N or WxH (e.g. 256 or 320x240), not {text!r}") from None
