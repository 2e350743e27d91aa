"""Names a user types (methods, suites, scenes, variants, frames): one rule for matching them and for the
"did you mean" that follows a miss. Stdlib only, so every layer can use it.

* `match_name`: the exact name, else the one known name equal to it ignoring case (``SSDGS`` -> ``ssdgs``);
  None when there is none or several (``Lego`` and ``lego`` both known: ambiguous, so no guess).
* `did_you_mean`: up to three known names close to a mistyped one (difflib's ratio ≥ 0.6, compared ignoring
  case), to follow the name in an error message: ``" (did you mean 'ssdgs'?)"``, or ``""`` when nothing is close.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

CLOSE_ENOUGH = 0.6  # difflib's default cutoff: 'ssgds' ~ 'ssdgs' (0.8), 'mini' !~ 'nrhints'
MAX_SUGGESTIONS = 3


def match_name(name: str, known: Iterable[str]) -> str | None:
    """``name`` itself when known, else the single known name equal to it ignoring case, else None."""
    known = list(known)
    if name in known:
        return name
    folded = [candidate for candidate in known if candidate.casefold() == name.casefold()]
    return folded[0] if len(folded) == 1 else None


def close_names(name: str, known: Iterable[str]) -> list[str]:
    """Up to `MAX_SUGGESTIONS` known names close to ``name`` (best first), compared ignoring case."""
    by_folded: dict[str, str] = {}
    for candidate in known:
        by_folded.setdefault(candidate.casefold(), candidate)
    close = difflib.get_close_matches(name.casefold(), list(by_folded), n=MAX_SUGGESTIONS, cutoff=CLOSE_ENOUGH)
    return [by_folded[folded] for folded in close]


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``" (did you mean 'a'?)"`` / ``" (did you mean 'a' or 'b'?)"`` for the names close to ``name``; ``""``
    when none is."""
    close = close_names(name, known)
    if not close:
        return ""
    quoted = [f"'{candidate}'" for candidate in close]
    listing = quoted[0] if len(quoted) == 1 else f"{', '.join(quoted[:-1])} or {quoted[-1]}"
    return f" (did you mean {listing}?)"


__all__ = ["close_names", "did_you_mean", "match_name"]
