"""sha256 manifests: recorded the first time a source is verified, checked on every later use."""

from __future__ import annotations

import hashlib
from pathlib import Path

from olatbench.atomic import write_json
from olatbench.datasets.jsontext import parse_json

MANIFEST_NAME = ".olatbench-manifest.json"


class IntegrityError(ValueError):
    """A file whose hash differs from the recorded one: names the file and both hashes."""


def sha256_file(path: Path, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file, read in chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(chunk):
            digest.update(block)
    return digest.hexdigest()


def check_hash(path: Path, expected: str) -> None:
    """Raise `IntegrityError` unless ``path`` hashes to ``expected``."""
    actual = sha256_file(path)
    if actual != expected:
        raise IntegrityError(f"{path.name}: sha256 mismatch: expected {expected}, got {actual}")


def scene_manifest(folder: Path) -> dict[str, str]:
    """{relative path: sha256} of every file below ``folder`` (the manifest itself excluded)."""
    return {
        str(p.relative_to(folder)): sha256_file(p)
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != MANIFEST_NAME
    }


def write_manifest(folder: Path, source: str, archives: dict[str, str]) -> Path:
    """Record the archives' and the unpacked files' hashes in ``folder``."""
    return write_json(
        folder / MANIFEST_NAME,
        {"source": source, "archives": archives, "files": scene_manifest(folder)},
    )


def read_manifest_files(path: Path) -> dict[str, str]:
    """The ``files`` entry ({relative path: sha256}) of a scene's manifest, its shape checked: a
    `ValueError` naming ``path`` and the field when the file is not UTF-8 JSON, not an object, or
    ``files`` is not an object of text values (a manifest edited or damaged by hand)."""
    try:
        data = parse_json(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: malformed manifest: not UTF-8 text ({error})") from None
    except OSError as error:
        raise ValueError(f"{path}: unreadable manifest ({error.strerror or error})") from None
    except ValueError as error:
        raise ValueError(f"{path}: malformed manifest: {error}") from None
    if not isinstance(data, dict):
        raise ValueError(
            f"{path}: malformed manifest: expected a JSON object, found {type(data).__name__}"
        )
    files = data.get("files")
    if not isinstance(files, dict):
        found = "nothing" if files is None else type(files).__name__
        raise ValueError(
            f"{path}: malformed manifest: key 'files': expected an object of file hashes, found "
            f"{found}"
        )
    for name, digest in files.items():
        if not isinstance(digest, str):
            raise ValueError(
                f"{path}: malformed manifest: key 'files.{name}': expected a sha256 as text, found "
                f"{type(digest).__name__}"
            )
    return files


def verify_folder(folder: Path) -> list[str]:
    """Problems found when re-hashing a downloaded scene against its manifest (empty = intact)."""
    path = folder / MANIFEST_NAME
    if not path.is_file():
        return [f"{folder}: no manifest ({MANIFEST_NAME}); it was not downloaded by olatbench"]
    try:
        recorded = read_manifest_files(path)
    except ValueError as error:
        return [str(error)]
    problems = []
    current = scene_manifest(folder)
    for name, digest in recorded.items():
        if name not in current:
            problems.append(f"{folder / name}: missing")
        elif current[name] != digest:
            problems.append(
                f"{folder / name}: sha256 mismatch: expected {digest}, got {current[name]}"
            )
    problems += [
        f"{folder / name}: not in the manifest" for name in current if name not in recorded
    ]
    return problems
