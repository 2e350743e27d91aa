"""sha256 manifests: recorded the first time a source is verified, checked on every later use."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from olatbench.atomic import write_json

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
    return {str(p.relative_to(folder)): sha256_file(p)
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name != MANIFEST_NAME}


def write_manifest(folder: Path, source: str, archives: dict[str, str]) -> Path:
    """Record the archives' and the unpacked files' hashes in ``folder``."""
    return write_json(folder / MANIFEST_NAME, {"source": source, "archives": archives,
                                               "files": scene_manifest(folder)})


def verify_folder(folder: Path) -> list[str]:
    """Problems found when re-hashing a downloaded scene against its manifest (empty = intact)."""
    path = folder / MANIFEST_NAME
    if not path.is_file():
        return [f"{folder}: no manifest ({MANIFEST_NAME}); it was not downloaded by olatbench"]
    try:
        recorded = json.loads(path.read_text())["files"]
    except (json.JSONDecodeError, KeyError) as error:
        return [f"{path}: malformed manifest ({error})"]
    problems = []
    current = scene_manifest(folder)
    for name, digest in recorded.items():
        if name not in current:
            problems.append(f"{folder / name}: missing")
        elif current[name] != digest:
            problems.append(f"{folder / name}: sha256 mismatch: expected {digest}, got {current[name]}")
    problems += [f"{folder / name}: not in the manifest" for name in current if name not in recorded]
    return problems
