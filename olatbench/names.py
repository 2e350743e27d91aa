"""Names a user types (methods, suites, scenes, variants, frames): one rule for matching them and
for the "did you mean" that follows a miss. Stdlib only, so every layer can use it.

* `match_name`: the exact name, else the one known name equal to it ignoring case
  (``SSDGS`` -> ``ssdgs``); None when there is none or several (``Lego`` and ``lego`` both known:
  ambiguous, so no guess).
* `did_you_mean`: up to three known names close to a mistyped one (difflib's ratio ≥ 0.6, compared
  ignoring case), to follow the name in an error message: ``" (did you mean 'ssdgs'?)"``, or ``""``
  when nothing is close.
* `path_component`: a name that becomes one folder of a run's path (suite, method, variant, scene)
  is checked once before any folder is made: never empty, ``.`` or ``..``, never holding a path
  separator or a control character, at most 255 bytes, so it cannot leave the output folder or land
  where another name's folder belongs.
* `case_twin`: the known name equal to a new one ignoring case: two such names are one folder on a
  case-insensitive disk (macOS, Windows), so a second one is refused where names are declared.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

CLOSE_ENOUGH = 0.6  # difflib's default cutoff: 'ssgds' ~ 'ssdgs' (0.8), 'mini' !~ 'nrhints'
MAX_SUGGESTIONS = 3
# the longest file name of ext4, APFS and NTFS (UTF-8 bytes; NTFS counts UTF-16 units)
MAX_COMPONENT_BYTES = 255


def match_name(name: str, known: Iterable[str]) -> str | None:
    """``name`` itself when known, else the single known name equal to it ignoring case, else
    None."""
    known = list(known)
    if name in known:
        return name
    folded = [candidate for candidate in known if candidate.casefold() == name.casefold()]
    return folded[0] if len(folded) == 1 else None


def close_names(name: str, known: Iterable[str]) -> list[str]:
    """Up to `MAX_SUGGESTIONS` known names close to ``name`` (best first), compared ignoring
    case."""
    by_folded: dict[str, str] = {}
    for candidate in known:
        by_folded.setdefault(candidate.casefold(), candidate)
    close = difflib.get_close_matches(
        name.casefold(), list(by_folded), n=MAX_SUGGESTIONS, cutoff=CLOSE_ENOUGH
    )
    return [by_folded[folded] for folded in close]


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``" (did you mean 'a'?)"`` / ``" (did you mean 'a' or 'b'?)"`` for the names close to
    ``name``; ``""`` when none is."""
    close = close_names(name, known)
    if not close:
        return ""
    quoted = [f"'{candidate}'" for candidate in close]
    listing = quoted[0] if len(quoted) == 1 else f"{', '.join(quoted[:-1])} or {quoted[-1]}"
    return f" (did you mean {listing}?)"


def path_component(name: str, what: str) -> str:
    """``name`` when it can name one folder below an output folder (module docstring); else a
    `ValueError` naming ``what`` (e.g. ``"suite"``) and the reason."""
    reason = None
    if not isinstance(name, str) or not name:
        reason = "it is empty"
    elif name in (".", ".."):
        reason = f"'{name}' is not a folder of its own"
    elif any(separator in name for separator in "/\\"):
        reason = "it holds a path separator"
    elif any(ord(char) < 32 or ord(char) == 127 for char in name):
        reason = "it holds a control character"
    elif len(name.encode("utf-8", "surrogateescape")) > MAX_COMPONENT_BYTES:
        reason = f"it is longer than {MAX_COMPONENT_BYTES} bytes"
    if reason is not None:
        raise ValueError(f"{what} name {name!r} cannot name a folder: {reason}")
    return name


def case_twin(name: str, known: Iterable[str]) -> str | None:
    """The first of ``known`` that differs from ``name`` only by case (the same folder on a
    case-insensitive disk), else None."""
    return next(
        (other for other in known if other != name and other.casefold() == name.casefold()), None
    )


__all__ = ["case_twin", "close_names", "did_you_mean", "match_name", "path_component"]
