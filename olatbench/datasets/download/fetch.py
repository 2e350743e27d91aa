"""Download, verify, unpack and lay out one scene: what ``olatbench datasets download`` runs."""

from __future__ import annotations

import fnmatch
import json
import os
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
_PART = re.compile(r"\.\d{3}$")


class ManualStepRequired(RuntimeError):
    """A source that olatbench cannot fetch by itself; the message says exactly what to do."""


@dataclass(frozen=True)
class RemoteFile:
    """One file to fetch: its archive name, URL, size/sha256 when the host publishes them, and whether the
    request carries the Hub token (`hub_headers`)."""

    name: str
    url: str
    size: int | None = None
    sha256: str | None = None
    hub: bool = False


def hub_endpoint(mirror: str | None = None) -> str:
    """The Hub to ask: ``mirror``, else ``$HF_ENDPOINT``, else ``https://huggingface.co`` (no trailing slash)."""
    return (mirror or os.environ.get("HF_ENDPOINT") or HF_ENDPOINT).rstrip("/")


def hub_headers() -> dict[str, str]:
    """``Authorization: Bearer $HF_TOKEN`` when ``$HF_TOKEN`` is set (gated or private repositories), else none.
    Sent to the Hub endpoint only: `transfer` drops it when the Hub redirects a download to its CDN."""
    token = os.environ.get("HF_TOKEN", "").strip()
    return {"Authorization": f"Bearer {token}"} if token else {}


def resolve_files(source: Source, mirror: str | None = None) -> list[RemoteFile]:
    """The files of ``source``, in archive-part order; ``mirror`` replaces the host (Hub endpoint or base URL).

    Raises `ManualStepRequired` for manual sources and for mirror-only sources without ``mirror``, and
    `transfer.DownloadError` when the host cannot be read or does not hold the expected files.
    """
    if source.kind == "manual":
        raise ManualStepRequired(source.instructions)
    if source.kind == "url":
        base = (mirror or source.base_url).rstrip("/")
        if not base:
            raise ManualStepRequired(source.instructions)
        files = [RemoteFile(path.rsplit("/", 1)[-1], f"{base}/{path}") for path in source.files]
    else:
        files = _hub_files(source, mirror)
    return _one_archive(source, files)


def resolve_revision(source: Source, endpoint: str) -> str:
    """The full commit id of ``source.revision``: itself when it is one (40 hex digits) or not hex (a branch), else
    the commit of ``main``'s history (every page of the Hub's commit listing) whose id starts with it."""
    revision = source.revision
    if len(revision) == 40 or not re.fullmatch(r"[0-9a-f]{4,39}", revision):
        return revision
    commits = transfer.fetch_json_pages(f"{endpoint}/api/datasets/{source.repo}/commits/main", headers=hub_headers())
    matches = sorted({str(c.get("id")) for c in commits if isinstance(c, dict)
                      and str(c.get("id", "")).startswith(revision)})
    if len(matches) != 1:
        found = "no commit" if not matches else f"{len(matches)} commits ({', '.join(matches)})"
        raise transfer.DownloadError(f"{source.repo}: {found} of main's history ({len(commits)} commits) starts "
                                     f"with the pinned revision {revision}")
    return matches[0]


def _hub_files(source: Source, mirror: str | None) -> list[RemoteFile]:
    """The scene's files as the Hub's tree API lists them (exact paths, or the archives matching the pattern)."""
    endpoint = hub_endpoint(mirror)
    revision = resolve_revision(source, endpoint)
    where = f"{source.repo}@{revision}"
    listing = transfer.fetch_json_pages(f"{endpoint}/api/datasets/{source.repo}/tree/{revision}?recursive=true",
                                        headers=hub_headers())
    entries = {str(e.get("path")): e for e in listing if isinstance(e, dict) and e.get("type") == "file"}
    held = ", ".join(sorted(entries)[:20]) or "nothing"
    if source.files:
        missing = [path for path in source.files if path not in entries]
        if missing:
            raise transfer.DownloadError(f"{where}: {', '.join(missing)} not found; the repository holds: {held}")
        chosen = list(source.files)
    else:
        chosen = sorted(path for path in entries if _ARCHIVE.search(path) and _matches(path, source.pattern))
        if not chosen:
            raise transfer.DownloadError(f"{where}: no archive matches '{source.pattern}'; "
                                         f"the repository holds: {held}")
    resolve = f"{endpoint}/datasets/{source.repo}/resolve/{revision}"
    files = []
    for path in chosen:
        lfs = entries[path].get("lfs") or {}
        files.append(RemoteFile(path.rsplit("/", 1)[-1], f"{resolve}/{path}", size=entries[path].get("size"),
                                sha256=lfs.get("oid") or lfs.get("sha256"), hub=True))
    return files


def _matches(path: str, pattern: str) -> bool:
    """Whether ``path`` matches the glob ``pattern`` folder by folder (``*`` never crosses a ``/``)."""
    parts, globs = path.split("/"), pattern.split("/")
    return len(parts) == len(globs) and all(fnmatch.fnmatchcase(p, g) for p, g in zip(parts, globs, strict=True))


def _one_archive(source: Source, files: list[RemoteFile]) -> list[RemoteFile]:
    """``files`` if they are one archive or the numbered parts (.001, .002, …) of one; otherwise an error."""
    files = sorted(files, key=lambda f: f.name)
    stems = {_ARCHIVE.sub(r".\1", f.name) for f in files}
    if len(files) > 1 and (len(stems) > 1 or not all(_PART.search(f.name) for f in files)):
        raise transfer.DownloadError(f"{source.name}: several archives match ({', '.join(f.name for f in files)}); "
                                     "expected one archive or the numbered parts of one")
    return files


def _fetch_verified(remote: RemoteFile, folder: Path, expected: str | None, progress) -> str:
    """Download one file (resuming) and check it against the published or recorded sha256."""
    target = folder / remote.name
    if not target.exists():
        transfer.download(remote.url, target, expected_size=remote.size, progress=progress,
                          headers=hub_headers() if remote.hub else None)
    digest = manifest.sha256_file(target)
    expected = remote.sha256 or expected
    if expected and digest != expected:
        bad = target.with_name(target.name + ".mismatch")
        target.replace(bad)
        raise manifest.IntegrityError(f"{remote.name}: sha256 mismatch: expected {expected}, got {digest} "
                                      f"(kept as {bad} for inspection; rerun to download again)")
    return digest


def _fetch_all(source: Source, files: list[RemoteFile], root: Path, label: str, jobs: int,
               progress: bool) -> dict[str, str]:
    """Download and verify ``files`` into ``root/.downloads/<source>``; return {file name: sha256}.

    Hashes of files the host does not publish are recorded in ``root/.olatbench-sources.json`` under
    ``<source>/<file>`` the first time and checked on every later download.
    """
    from tqdm.auto import tqdm

    known_path = root / KNOWN_HASHES
    known = json.loads(known_path.read_text()) if known_path.is_file() else {}
    cache = root / DOWNLOADS / source.name
    cache.mkdir(parents=True, exist_ok=True)
    total = sum(f.size for f in files if f.size) or None
    with tqdm(total=total, unit="B", unit_scale=True, desc=label, disable=not progress) as bar, \
            ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        digests = list(pool.map(lambda f: _fetch_verified(f, cache, known.get(f"{source.name}/{f.name}"), bar),
                                files))
    recorded = {f.name: d for f, d in zip(files, digests, strict=True)}
    known.update({f"{source.name}/{name}": digest for name, digest in recorded.items()})
    write_json(known_path, known)
    return recorded


def _scene_folder(unpacked: Path) -> Path:
    """The folder of the scene inside an unpacked archive: a lone top-level folder, or the root."""
    entries = [p for p in unpacked.iterdir() if not p.name.startswith(("__MACOSX", "."))]
    return entries[0] if len(entries) == 1 and entries[0].is_dir() else unpacked


def download_scene(suite: str, scene: str, root: Path, *, source: str | None = None, mirror: str | None = None,
                   jobs: int = 4, progress: bool = True) -> Path:
    """Fetch one scene into ``root/<scene>`` (canonical name) and return that folder.

    Sources are tried in order (`sources_for`); one that needs a manual step or cannot be downloaded
    passes to the next, and the error lists why each failed. An intact earlier download is kept.
    Archives are checked against published hashes or against the hash recorded the first time
    (``root/.olatbench-sources.json``); a mismatch stops at once. Unpacking happens in a temporary
    folder renamed into place only after the scene validates, so no half-unpacked scene is ever left.
    """
    root = Path(root)
    destination = root / scene
    if destination.exists() and not manifest.verify_folder(destination):
        return destination
    errors: list[str] = []
    manual_only = True
    for candidate in sources_for(suite, scene, source):
        try:
            files = resolve_files(candidate, mirror)
            recorded = _fetch_all(candidate, files, root, f"{suite}/{scene}", jobs, progress)
        except ManualStepRequired as error:
            errors.append(f"[{candidate.name}] {error}")
        except transfer.DownloadError as error:
            errors.append(f"[{candidate.name}] {error}")
            manual_only = False
        else:
            return _install(suite, scene, candidate, files, recorded, root)
    failure = ManualStepRequired if manual_only else transfer.DownloadError
    raise failure(f"{suite}/{scene}: no source could be used:\n" + "\n".join(errors))


def _install(suite: str, scene: str, source: Source, files: list[RemoteFile], recorded: dict[str, str],
             root: Path) -> Path:
    """Join the parts, unpack, validate and rename the scene into ``root/<scene>``."""
    from olatbench.datasets.validate import validate_folder

    cache = root / DOWNLOADS / source.name
    destination = root / scene
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
        manifest.write_manifest(folder, source.name, recorded)
        if destination.exists():
            shutil.rmtree(destination)
        folder.rename(destination)
    return destination
