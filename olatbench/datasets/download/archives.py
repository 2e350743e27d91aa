"""Safe unpacking: no absolute paths, no ``..``, no links, nothing outside the destination, no
decompression bomb.

Every failure is one exception naming the archive: `UnsafeArchiveError` for a member that must not
be written (including an archive that unpacks to more than `unpack_limit` bytes), `ArchiveError` for
an archive that cannot be read (truncated, corrupt, not an archive) or whose members cannot be laid
out as files (a file and a folder of one name, a name too long for the file system). Errors of the
disk being written (full, read-only) stay `OSError`.
"""

from __future__ import annotations

import errno
import lzma
import shutil
import stat
import tarfile
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import IO

UNPACK_RATIO = 20  # an archive may unpack to at most this many times its own size...
# ...or 64 MiB, whichever is larger (scene archives hold PNG/EXR: ratio about 1)
UNPACK_FLOOR = 64 << 20
MAX_MEMBERS = 1_000_000  # the largest official scene holds a few tens of thousands of files
CHUNK = 1 << 20


class UnsafeArchiveError(ValueError):
    """An archive member that would land outside the destination folder, a link, or an archive too
    large."""


class ArchiveError(ValueError):
    """An archive that cannot be read (truncated, corrupt, not a zip or tar file) or unpacked as
    files (members that collide, a name too long)."""


def unpack_limit(archive_bytes: int) -> int:
    """How many bytes an archive of ``archive_bytes`` may unpack to: `UNPACK_RATIO` × its size, at
    least `UNPACK_FLOOR`."""
    return max(UNPACK_RATIO * archive_bytes, UNPACK_FLOOR)


def join_parts(parts: list[Path], target: Path) -> Path:
    """Concatenate ``archive.zip.001``, ``.002``… (in the given order) into ``target``."""
    with open(target, "wb") as output:
        for part in parts:
            with open(part, "rb") as handle:
                shutil.copyfileobj(handle, output, CHUNK)
    return target


def _safe_member_path(destination: Path, name: str, archive: Path) -> Path:
    pure = PurePosixPath(name.replace("\\", "/"))
    if pure.is_absolute() or ".." in pure.parts or (pure.parts and pure.parts[0].endswith(":")):
        raise UnsafeArchiveError(f"{archive.name}: member '{name}' escapes the destination")
    target = (destination / Path(*pure.parts)).resolve() if pure.parts else destination.resolve()
    if destination.resolve() not in (target, *target.parents):
        raise UnsafeArchiveError(f"{archive.name}: member '{name}' escapes the destination")
    return target


# What reading a damaged archive raises, by layer: tar and zip structure, gzip/bz2 streams (EOFError
# when cut short, zlib.error or an OSError without errno such as gzip.BadGzipFile when corrupt), xz
# streams.
_DAMAGE = (tarfile.TarError, zipfile.BadZipFile, EOFError, zlib.error, lzma.LZMAError, OSError)


@contextmanager
def _reading(archive: Path) -> Iterator[None]:
    """Turn the errors of a damaged archive into one `ArchiveError` naming it; an `OSError` with an
    ``errno`` (disk full, permission denied) is the machine's, not the archive's, and passes
    unchanged."""
    try:
        yield
    except _DAMAGE as error:
        if isinstance(error, OSError) and error.errno is not None:
            raise
        raise ArchiveError(
            f"{archive.name}: damaged or truncated archive ({type(error).__name__}: {error})"
        ) from None


def _open_archive(archive: Path) -> zipfile.ZipFile | tarfile.TarFile:
    """The archive opened for reading, whichever of zip or tar it is."""
    if zipfile.is_zipfile(archive):
        return zipfile.ZipFile(archive)
    if tarfile.is_tarfile(archive):
        return tarfile.open(archive)
    raise ArchiveError(
        f"{archive.name}: damaged or truncated archive (neither a zip nor a tar file)"
    )


def _members(
    bundle: zipfile.ZipFile | tarfile.TarFile, archive: Path
) -> list[tuple[str, str, object]]:
    """(name, kind, handle) of every member; kind is ``file``, ``dir`` or ``link``
    (links, devices, fifos)."""
    if isinstance(bundle, zipfile.ZipFile):
        return [
            (
                m.filename,
                "link" if stat.S_ISLNK(m.external_attr >> 16) else "dir" if m.is_dir() else "file",
                m,
            )
            for m in bundle.infolist()
        ]
    members = [
        (m.name, "file" if m.isfile() else "dir" if m.isdir() else "link", m)
        for m in bundle.getmembers()
    ]
    _check_tar_end(bundle, archive)
    return members


def _check_tar_end(bundle: tarfile.TarFile, archive: Path) -> None:
    """Raise `ArchiveError` unless only zero padding follows the last member. `tarfile` ends its
    listing quietly at the first damaged header after the first one, so a corrupt tar would
    otherwise unpack as a shorter tree; reading a compressed stream to its end also checks its
    CRC."""
    assert bundle.fileobj is not None
    bundle.fileobj.seek(bundle.offset)
    while block := bundle.fileobj.read(CHUNK):
        if block.count(0) != len(block):
            raise ArchiveError(
                f"{archive.name}: damaged or truncated archive (a damaged member header at byte "
                f"{bundle.offset} ends the readable part; data follows it)"
            )


def _check_members(
    members: list[tuple[str, str, object]], destination: Path, archive: Path
) -> None:
    """Refuse the whole archive before anything is written when one member is unsafe."""
    if len(members) > MAX_MEMBERS:
        raise UnsafeArchiveError(
            f"{archive.name}: {len(members)} members, more than the limit of {MAX_MEMBERS}"
        )
    files: dict[Path, str] = {}
    folders: dict[Path, str] = {}
    for name, kind, _ in members:
        target = _safe_member_path(destination, name, archive)
        if kind == "link":
            raise UnsafeArchiveError(f"{archive.name}: member '{name}' is a link or device")
        if kind == "file" and target == destination.resolve():
            raise UnsafeArchiveError(
                f"{archive.name}: member '{name}' is a file without a file name"
            )
        (files if kind == "file" else folders)[target] = name
        for parent in target.parents:
            if parent == destination.resolve():
                break
            folders.setdefault(parent, name)
    for target, name in files.items():
        if target in folders:
            raise ArchiveError(
                f"{archive.name}: member '{name}' is a file, and member '{folders[target]}' makes "
                "a folder of the same name; the archive cannot be unpacked as files"
            )


def _copy_bounded(source: IO[bytes], target: Path, budget: int, archive: Path, limit: int) -> int:
    """Copy ``source`` into ``target``, never more than ``budget`` bytes; the bytes written."""
    written = 0
    with open(target, "wb") as output:
        while block := source.read(CHUNK):
            written += len(block)
            if written > budget:
                raise UnsafeArchiveError(
                    f"{archive.name}: unpacks to more than {limit} bytes (the limit for an "
                    f"archive of {archive.stat().st_size} bytes: {UNPACK_RATIO} × its size, "
                    f"at least {UNPACK_FLOOR >> 20} MiB); refusing a likely decompression bomb"
                )
            output.write(block)
    return written


def extract(archive: Path, destination: Path, max_bytes: int | None = None) -> list[Path]:
    """Unpack a zip or tar archive into ``destination``; refuse unsafe members before writing
    anything.

    ``max_bytes`` bounds the bytes written (default `unpack_limit` of the archive's size); it is
    counted while unpacking, so sizes an archive declares falsely do not matter. Raises
    `UnsafeArchiveError` or `ArchiveError`.
    """
    limit = unpack_limit(archive.stat().st_size) if max_bytes is None else max_bytes
    destination.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    budget = limit
    with _reading(archive), _open_archive(archive) as bundle:
        members = _members(bundle, archive)
        _check_members(members, destination, archive)
        for name, kind, member in members:
            target = _safe_member_path(destination, name, archive)
            with _laying_out(archive, name):
                if kind == "dir":
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                source = (
                    bundle.open(member)
                    if isinstance(bundle, zipfile.ZipFile)
                    else bundle.extractfile(member)
                )
                with source:
                    budget -= _copy_bounded(source, target, budget, archive, limit)
            written.append(target)
    return written


# What the file system answers to a member the archive itself makes impossible to write: a name too
# long, or a file and a folder of one name that `_check_members` could not see (names differing only
# in case on a case-insensitive file system, a zip that stores one name twice).
_LAYOUT_ERRORS = (errno.ENAMETOOLONG, errno.EEXIST, errno.ENOTDIR, errno.EISDIR)


@contextmanager
def _laying_out(archive: Path, name: str) -> Iterator[None]:
    """Turn an `OSError` caused by member ``name`` itself into an `ArchiveError` naming the archive
    and the member (not the temporary folder it was unpacked into); the disk's own errors
    (full, read-only) pass unchanged."""
    try:
        yield
    except OSError as error:
        if error.errno not in _LAYOUT_ERRORS:
            raise
        raise ArchiveError(
            f"{archive.name}: member '{name[:120]}{'…' if len(name) > 120 else ''}' cannot be "
            f"unpacked as a file ({error.strerror})"
        ) from None
