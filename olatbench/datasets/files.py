"""Whether a path from a dataset is a file that can be read: one `DatasetError` naming it otherwise.

Symbolic links are followed (a ``train/`` folder linked to another disk is the user's to make); a
link that loops, a folder where a file belongs, or a name OpenImageIO cannot take (not valid UTF-8)
is said plainly.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from olatbench.datasets.errors import DatasetError


def present(path: Path) -> bool:
    """Whether anything is at ``path``: a file, a folder, or a symbolic link (even a looping or
    dangling one)."""
    return os.path.lexists(path)


def require_file(path: Path, what: str = "file") -> None:
    """Raise `DatasetError` naming ``path`` unless it is a regular file (after following links) we
    may open.

    ``what`` names the expected content in the message ("image file", "JSON file").
    """
    article = "an" if what[0] in "aeiou" else "a"
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        dangling = " (a symbolic link to a missing file)" if path.is_symlink() else ""
        raise DatasetError(f"{what} not found{dangling}", path=path) from None
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise DatasetError(
                "symbolic link loop: the link never reaches a file", path=path
            ) from None
        raise DatasetError(f"cannot read ({error.strerror or error})", path=path) from None
    if stat.S_ISDIR(mode):
        raise DatasetError(f"is a folder, expected {article} {what}", path=path)
    if not stat.S_ISREG(mode):
        raise DatasetError(
            f"is not a regular file (a device, socket or pipe), expected {article} {what}",
            path=path,
        )


def require_utf8_name(path: Path) -> None:
    """Raise `DatasetError` when ``path`` holds bytes that are not UTF-8 (OpenImageIO takes UTF-8
    names only)."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        raise DatasetError(
            "the path is not valid UTF-8, which OpenImageIO cannot open; rename the file or folder "
            "(e.g. convmv -f latin1 -t utf-8)",
            path=path,
        ) from None
