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


def extract(archive: Path, destination: Path) -> list[Path]:
    """Unpack a zip or tar archive into ``destination``; refuse unsafe members before writing anything."""
    destination.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    if zipfile.is_zipfile(archive):
        with zipfile.ZipFile(archive) as bundle:
            members = bundle.infolist()
            for member in members:
                _safe_member_path(destination, member.filename, archive)
                if stat.S_ISLNK(member.external_attr >> 16):
                    raise UnsafeArchiveError(f"{archive.name}: member '{member.filename}' is a symbolic link")
            for member in members:
                target = _safe_member_path(destination, member.filename, archive)
                if member.is_dir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                with bundle.open(member) as source, open(target, "wb") as output:
                    shutil.copyfileobj(source, output, 1 << 20)
                written.append(target)
        return written
    if tarfile.is_tarfile(archive):
        with tarfile.open(archive) as bundle:
            members = bundle.getmembers()
            for member in members:
                _safe_member_path(destination, member.name, archive)
                if not (member.isfile() or member.isdir()):
                    raise UnsafeArchiveError(f"{archive.name}: member '{member.name}' is a link or device")
            for member in members:
                target = _safe_member_path(destination, member.name, archive)
                if member.isdir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                with bundle.extractfile(member) as source, open(target, "wb") as output:
                    shutil.copyfileobj(source, output, 1 << 20)
                written.append(target)
        return written
    raise ValueError(f"{archive.name}: not a zip or tar archive")
