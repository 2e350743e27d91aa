"""Atomic file writes: a result is either absent or complete, never half-written.

A write that the file system refuses (a read-only folder, a full disk, no permission) raises
`WriteError`: an `OSError` whose message names the file and the reason, with the file as it was
before (or absent).
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


class WriteError(OSError):
    """A file that could not be written: ``str()`` is one line naming the file and the reason;
    ``errno`` is the cause's (``errno.EROFS``, ``errno.ENOSPC``, ...)."""

    def __init__(self, path: str | Path, cause: OSError) -> None:
        super().__init__(cause.errno, cause.strerror or str(cause), str(path))

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


def _umask() -> int:
    """The process umask (reading it requires setting it; it is restored at once)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); rename it onto ``path`` on success.

    On an exception the temporary file is removed and ``path`` is left as it was; an `OSError` of
    the file system (read-only, full, not permitted) becomes a `WriteError` naming ``path``.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(
            prefix=f".{path.name}.", suffix=path.suffix or ".tmp", dir=path.parent
        )
        os.close(handle)
    except WriteError:
        raise
    except OSError as error:
        raise WriteError(path, error) from error
    try:
        yield Path(temporary)
        # mkstemp makes owner-only files; results are for everyone
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except WriteError:
        raise
    except OSError as error:
        raise WriteError(path, error) from error
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (fsync before the rename)."""
    with atomic_path(path) as temporary, open(temporary, "wb") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | Path, data: Any, indent: int = 2) -> Path:
    """Write ``data`` as JSON atomically; NaN/Inf are refused (they are not JSON)."""
    return write_text(
        path, json.dumps(data, indent=indent, allow_nan=False, sort_keys=False) + "\n"
    )
