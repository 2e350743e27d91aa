"""Download, verify, unpack and lay out one scene: what ``olatbench datasets download`` runs."""

from __future__ import annotations

import json
import re
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from olatbench.atomic import write_json
from olatbench.datasets.download import archives, manifest, transfer
from olatbench.datasets.download.sources import HF_ENDPOINT, Source, sources_for
from olatbench.datasets.errors import DatasetError

KNOWN_HASHES = ".olatbench-sources.json"
DOWNLOADS = ".downloads"
_ARCHIVE = re.compile(r"\.(zip|tar|tar\.gz|tgz|tar\.bz2|tar\.xz)(\.\d{3})?$", re.IGNORECASE)


class ManualStepRequired(RuntimeError):
    """A source that olatbench cannot fetch by itself; the message says exactly what to do."""


@dataclass(frozen=True)
class RemoteFile:
    """One file to fetch: its archive name, URL, and size/sha256 when the host publishes them."""

    name: str
    url: str
    size: int | None = None
    sha256: str | None = None


def resolve_files(source: Source, mirror: str | None = None) -> list[RemoteFile]:
    """The files of ``source``; for Hugging Face sources, asked of the Hub's tree API (``mirror`` replaces the host)."""
    if source.kind == "manual":
        raise ManualStepRequired(source.instructions)
    if source.kind == "mirror":
        if not mirror:
            raise ManualStepRequired(source.instructions)
        return [RemoteFile(name, f"{mirror.rstrip('/')}/{name}") for name in source.archives]
    endpoint = (mirror or HF_ENDPOINT).rstrip("/")
    listing = transfer.fetch_json(f"{endpoint}/api/datasets/{source.repo}/tree/main?recursive=true")
    if not isinstance(listing, list):
        raise transfer.DownloadError(f"{endpoint}: unexpected answer listing {source.repo}")
    prefix = source.archive_prefix.lower()
    files = []
    for entry in listing:
        path = str(entry.get("path", ""))
        name = path.rsplit("/", 1)[-1]
        if entry.get("type") != "file" or not _ARCHIVE.search(name) or not name.lower().startswith(prefix):
            continue
        if source.prefix and not path.startswith(source.prefix):
            continue
        lfs = entry.get("lfs") or {}
        files.append(RemoteFile(name, f"{endpoint}/datasets/{source.repo}/resolve/main/{path}",
                                size=entry.get("size"), sha256=lfs.get("oid") or lfs.get("sha256")))
    if not files:
        names = sorted(str(e.get("path")) for e in listing if e.get("type") == "file")
        raise transfer.DownloadError(f"{source.repo}: no archive starting with '{source.archive_prefix}'; "
                                 f"the repository holds: {', '.join(names[:20]) or 'nothing'}")
    return sorted(files, key=lambda f: f.name)


def _fetch_verified(remote: RemoteFile, folder: Path, known: dict[str, str], progress) -> str:
    """Download one file (resuming) and check it against the published or recorded sha256."""
    target = folder / remote.name
    if not target.exists():
        transfer.download(remote.url, target, expected_size=remote.size, progress=progress)
    digest = manifest.sha256_file(target)
    expected = remote.sha256 or known.get(remote.name)
    if expected and digest != expected:
        bad = target.with_name(target.name + ".mismatch")
        target.replace(bad)
        raise manifest.IntegrityError(f"{remote.name}: sha256 mismatch: expected {expected}, got {digest} "
                                      f"(kept as {bad} for inspection; rerun to download again)")
    return digest


def _scene_folder(unpacked: Path) -> Path:
    """The folder of the scene inside an unpacked archive: a lone top-level folder, or the root."""
    entries = [p for p in unpacked.iterdir() if not p.name.startswith(("__MACOSX", "."))]
    return entries[0] if len(entries) == 1 and entries[0].is_dir() else unpacked


def download_scene(suite: str, scene: str, root: Path, *, source: str | None = None, mirror: str | None = None,
                   jobs: int = 4, progress: bool = True) -> Path:
    """Fetch one scene into ``root/<scene>`` (canonical name) and return that folder.

    An intact earlier download is kept. Archives are checked against published hashes or against the
    hash recorded the first time (``root/.olatbench-sources.json``); unpacking happens in a temporary
    folder renamed into place only after the scene validates, so no half-unpacked scene is ever left.
    """
    from tqdm.auto import tqdm

    from olatbench.datasets.validate import validate_folder

    root = Path(root)
    destination = root / scene
    if destination.exists() and not manifest.verify_folder(destination):
        return destination
    errors: list[str] = []
    for candidate in sources_for(suite, scene, source):
        try:
            files = resolve_files(candidate, mirror)
        except (ManualStepRequired, transfer.DownloadError) as error:
            errors.append(f"[{candidate.name}] {error}")
            continue
        break
    else:
        raise ManualStepRequired(f"{suite}/{scene}: no source could be used:\n" + "\n".join(errors))
    known_path = root / KNOWN_HASHES
    known = json.loads(known_path.read_text()) if known_path.is_file() else {}
    cache = root / DOWNLOADS / candidate.name
    cache.mkdir(parents=True, exist_ok=True)
    total = sum(f.size for f in files if f.size) or None
    with tqdm(total=total, unit="B", unit_scale=True, desc=f"{suite}/{scene}", disable=not progress) as bar, \
            ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        digests = list(pool.map(lambda f: _fetch_verified(f, cache, known, bar), files))
    recorded = {f.name: d for f, d in zip(files, digests, strict=True)}
    known.update(recorded)
    write_json(known_path, known)

    archive = cache / files[0].name
    if len(files) > 1:
        archive = archives.join_parts([cache / f.name for f in files], cache / _ARCHIVE.sub(r".\1", files[0].name))
    with tempfile.TemporaryDirectory(prefix=f".unpack-{scene}-", dir=root) as temporary:
        unpacked = Path(temporary) / "content"
        archives.extract(archive, unpacked)
        folder = _scene_folder(unpacked)
        report = validate_folder(folder)  # a tree that is not a valid scene is refused before it is put in place
        if not report.ok:
            first = "; ".join(f"{issue.message} ({issue.path or ''} {issue.frame or ''})".strip()
                              for issue in report.errors[:3])
            raise DatasetError(f"{suite}/{scene}: the unpacked archive is not a valid scene: {first}",
                               path=archive)
        manifest.write_manifest(folder, candidate.name, recorded)
        if destination.exists():
            shutil.rmtree(destination)
        folder.rename(destination)
    return destination
