"""Safe unpacking: no absolute paths, no ``..``, no links, nothing outside the destination."""

from __future__ import annotations

import shutil
import stat
import tarfile
import zipfile
from pathlib import Path, PurePosixPath


class UnsafeArchiveError(ValueError):
    """An archive member that would land outside the destination folder."""


def join_parts(parts: list[Path], target: Path) -> Path:
    """Concatenate ``archive.zip.001``, ``.002``… (in the given order) into ``target``."""
    with open(target, "wb") as output:
        for part in parts:
            with open(part, "rb") as handle:
                shutil.copyfileobj(handle, output, 1 << 20)
    return target


def _safe_member_path(destination: Path, name: str, archive: Path) -> Path:
    pure = PurePosixPath(name.replace("\\", "/"))
    if pure.is_absolute() or ".." in pure.parts or (pure.parts and pure.parts[0].endswith(":")):
        raise UnsafeArchiveError(f"{archive.name}: member '{name}' escapes the destination")
    target = (destination / Path(*pure.parts)).resolve() if pure.parts else destination.resolve()
    if destination.resolve() not in (target, *target.parents):
        raise UnsafeArchiveError(f"{archive.name}: member '{name}' escapes the destination")
    return target


def _open_archive(archive: Path) -> zipfile.ZipFile | tarfile.TarFile:
    """The archive opened for reading, whichever of zip or tar it is."""
    if zipfile.is_zipfile(archive):
        return zipfile.ZipFile(archive)
    if tarfile.is_tarfile(archive):
        return tarfile.open(archive)
    raise ValueError(f"{archive.name}: not a zip or tar archive")


def _members(bundle: zipfile.ZipFile | tarfile.TarFile) -> list[tuple[str, str, object]]:
    """(name, kind, handle) of every member; kind is ``file``, ``dir`` or ``link`` (links, devices, fifos)."""
    if isinstance(bundle, zipfile.ZipFile):
        return [(m.filename, "link" if stat.S_ISLNK(m.external_attr >> 16) else "dir" if m.is_dir() else "file", m)
                for m in bundle.infolist()]
    return [(m.name, "file" if m.isfile() else "dir" if m.isdir() else "link", m) for m in bundle.getmembers()]


def extract(archive: Path, destination: Path) -> list[Path]:
    """Unpack a zip or tar archive into ``destination``; refuse unsafe members before writing anything."""
    destination.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with _open_archive(archive) as bundle:
        members = _members(bundle)
        for name, kind, _ in members:
            _safe_member_path(destination, name, archive)
            if kind == "link":
                raise UnsafeArchiveError(f"{archive.name}: member '{name}' is a link or device")
        for name, kind, member in members:
            target = _safe_member_path(destination, name, archive)
            if kind == "dir":
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            source = bundle.open(member) if isinstance(bundle, zipfile.ZipFile) else bundle.extractfile(member)
            with source, open(target, "wb") as output:
                shutil.copyfileobj(source, output, 1 << 20)
            written.append(target)
    return written
