"""Image sizes: the one parser and the one bound every option and file giving a size goes through,
before anything of that size is allocated.

A side is a whole number of pixels from a minimum (1 unless the caller needs more) to `MAX_SIDE`.
The bound is libx264's largest frame side (its encoder refuses anything wider or taller, so a video
of a larger render fails only after every frame was rendered); an image of 16384² pixels already
takes 3 GiB as float32 RGB, so no training, render or report size is worth more. The messages say
what is wrong, not where: each caller names its flag, file or field.
"""

from __future__ import annotations

import math

MAX_SIDE = 16_384  # pixels, per side: libx264's largest frame side


def checked_side(value: object, minimum: int = 1) -> int:
    """``value`` (an int, or a float holding a whole number, as JSON may write one) as pixels in
    [``minimum``, `MAX_SIDE`]; a `ValueError` saying the accepted range otherwise."""
    whole = isinstance(value, int) or (
        isinstance(value, float) and math.isfinite(value) and value.is_integer()
    )
    if isinstance(value, bool) or not whole:
        raise ValueError(
            f"expected a whole number of pixels from {minimum} to {MAX_SIDE}, not {value!r}"
        )
    side = int(value)  # type: ignore[call-overload]
    if not minimum <= side <= MAX_SIDE:
        raise ValueError(f"{side} pixels is outside {minimum} to {MAX_SIDE}")
    return side


def checked_size(width: object, height: object, minimum: int = 1) -> tuple[int, int]:
    """(width, height) checked by `checked_side`; the `ValueError` names the side that is wrong."""
    sides = []
    for name, value in (("width", width), ("height", height)):
        try:
            sides.append(checked_side(value, minimum))
        except ValueError as error:
            raise ValueError(f"{name}: {error}") from None
    return sides[0], sides[1]


def parse_size(text: str, minimum: int = 1) -> tuple[int, int]:
    """``"N"`` (N × N) or ``"WxH"`` (``x`` or ``X``, spaces around the text ignored) as
    (width, height) in pixels, each side checked by `checked_side`; a `ValueError` saying the
    accepted forms or range otherwise."""
    width, separator, height = str(text).strip().lower().partition("x")
    try:
        # "256x" has an empty height: refused
        parsed = int(width), int(height if separator else width)
    except ValueError:
        raise ValueError(f"expected N or WxH (e.g. 256 or 320x240), not {text!r}") from None
    if not separator:
        return (checked_side(parsed[0], minimum),) * 2
    return checked_size(*parsed, minimum=minimum)
