"""The one exception type of the data layer: it names the file, the frame and the key (and its one
refinement, `OutputExistsError`, for a write that would replace a scene: the caller's choice, not
bad data)."""

from __future__ import annotations

import os
from pathlib import Path


def printable(text: Path | str) -> str:
    """``text`` (a path, or a message holding one) safe to print: bytes of a file name that are not
    UTF-8 (from another encoding, kept by Python as lone surrogates) are shown as ``\\xff``, so that
    printing never fails."""
    text = str(text)
    try:
        return os.fsencode(text).decode("utf-8", "backslashreplace")
    # a lone surrogate that is no escaped byte (e.g. "\\ud800" written in a JSON file)
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


class DatasetError(ValueError):
    """Bad or missing dataset input, reported once with where it was found.

    ``path`` is the offending file, ``frame`` the frame id (or index) and ``key``
    the JSON key, when known. ``str(error)`` is a single readable line.
    """

    def __init__(
        self,
        message: str,
        *,
        path: Path | str | None = None,
        frame: str | int | None = None,
        key: str | None = None,
    ) -> None:
        self.message = message
        self.path = Path(path) if path is not None else None
        self.frame = frame
        self.key = key
        super().__init__(self._render())

    def _render(self) -> str:
        where = []
        if self.path is not None:
            where.append(str(self.path))
        if self.frame is not None:
            where.append(f"frame {self.frame}")
        if self.key is not None:
            where.append(f"key '{self.key}'")
        return printable(": ".join([", ".join(where), self.message]) if where else self.message)


class OutputExistsError(DatasetError):
    """A scene already exists where one is to be written (the CLI reports it as a usage error)."""
