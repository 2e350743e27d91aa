"""The one exception type of the data layer: it names the file, the frame and the key."""

from __future__ import annotations

from pathlib import Path


class DatasetError(ValueError):
    """Bad or missing dataset input, reported once with where it was found.

    ``path`` is the offending file, ``frame`` the frame id (or index) and ``key``
    the JSON key, when known. ``str(error)`` is a single readable line.
    """

    def __init__(self, message: str, *, path: Path | str | None = None, frame: str | int | None = None,
                 key: str | None = None) -> None:
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
        return f"{': '.join([', '.join(where), self.message]) if where else self.message}"
