"""Download, verify, unpack and lay out one scene: what ``olatbench datasets download`` runs."""

from __future__ import annotations

import fnmatch
import os
import re
import shlex
import tempfile
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from olatbench.atomic import write_json
from olatbench.datasets.download import archives, manifest, transfer
from olatbench.datasets.download.archives import ArchiveError, UnsafeArchiveError
from olatbench.datasets.download.sources import HF_ENDPOINT, Source, sources_for
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.files import present
from olatbench.datasets.jsontext import parse_json

KNOWN_HASHES = ".olatbench-sources.json"
DOWNLOADS = ".downloads"
_ARCHIVE = re.compile(r"\.(zip|tar|tar\.gz|tgz|tar\.bz2|tar\.xz)(\.\d{3})?$", re.IGNORECASE)
_PART = re.compile(r"\.\d{3}$")


class ManualStepRequired(RuntimeError):
    """A source that olatbench cannot fetch by itself; the message says exactly what to do."""


@dataclass(frozen=True)
class RemoteFile:
    """One file to fetch: its archive name, URL, size/sha256 when the host publishes them, and
    whether the request carries the Hub token (`hub_headers`)."""

    name: str
    url: str
    size: int | None = None
    sha256: str | None = None
    hub: bool = False


def hub_endpoint(mirror: str | None = None) -> str:
    """The Hub to ask: ``mirror``, else ``$HF_ENDPOINT``, else ``https://huggingface.co``
    (no trailing slash)."""
    return (mirror or os.environ.get("HF_ENDPOINT") or HF_ENDPOINT).rstrip("/")


def hub_headers() -> dict[str, str]:
    """``Authorization: Bearer $HF_TOKEN`` when ``$HF_TOKEN`` is set
    (gated or private repositories), else none. Sent to the Hub endpoint only: `transfer` drops it
    when the Hub redirects a download to its CDN."""
    token = os.environ.get("HF_TOKEN", "").strip()
    return {"Authorization": f"Bearer {token}"} if token else {}


def resolve_files(source: Source, mirror: str | None = None) -> list[RemoteFile]:
    """The files of ``source``, in archive-part order; ``mirror`` replaces the host
    (Hub endpoint or base URL).

    Raises `ManualStepRequired` for manual sources and for mirror-only sources without ``mirror``,
    and `transfer.DownloadError` when the host cannot be read or does not hold the expected files.
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
    """The full commit id of ``source.revision``: itself when it is one (40 hex digits) or not hex
    (a branch), else the commit of ``main``'s history (every page of the Hub's commit listing) whose
    id starts with it."""
    revision = source.revision
    if len(revision) == 40 or not re.fullmatch(r"[0-9a-f]{4,39}", revision):
        return revision
    commits = transfer.fetch_json_pages(
        f"{endpoint}/api/datasets/{source.repo}/commits/main", headers=hub_headers()
    )
    matches = sorted(
        {
            str(c.get("id"))
            for c in commits
            if isinstance(c, dict) and str(c.get("id", "")).startswith(revision)
        }
    )
    if len(matches) != 1:
        found = "no commit" if not matches else f"{len(matches)} commits ({', '.join(matches)})"
        raise transfer.DownloadError(
            f"{source.repo}: {found} of main's history ({len(commits)} commits) starts "
            f"with the pinned revision {revision}"
        )
    return matches[0]


def _hub_files(source: Source, mirror: str | None) -> list[RemoteFile]:
    """The scene's files as the Hub's tree API lists them (exact paths, or the archives matching the
    pattern)."""
    endpoint = hub_endpoint(mirror)
    revision = resolve_revision(source, endpoint)
    where = f"{source.repo}@{revision}"
    url = f"{endpoint}/api/datasets/{source.repo}/tree/{revision}?recursive=true"
    entries = _hub_listing(transfer.fetch_json_pages(url, headers=hub_headers()), url)
    held = ", ".join(sorted(entries)[:20]) or "nothing"
    if source.files:
        missing = [path for path in source.files if path not in entries]
        if missing:
            raise transfer.DownloadError(
                f"{where}: {', '.join(missing)} not found; the repository holds: {held}"
            )
        chosen = list(source.files)
    else:
        chosen = sorted(
            path for path in entries if _ARCHIVE.search(path) and _matches(path, source.pattern)
        )
        if not chosen:
            raise transfer.DownloadError(
                f"{where}: no archive matches '{source.pattern}'; the repository holds: {held}"
            )
    resolve = f"{endpoint}/datasets/{source.repo}/resolve/{revision}"
    files = []
    for path in chosen:
        lfs = entries[path].get("lfs") or {}
        files.append(
            RemoteFile(
                path.rsplit("/", 1)[-1],
                f"{resolve}/{path}",
                size=entries[path].get("size"),
                sha256=lfs.get("oid") or lfs.get("sha256"),
                hub=True,
            )
        )
    return files


def _hub_listing(listing: list, url: str) -> dict[str, dict]:
    """{path: entry} of the files in a Hub tree listing, the fields olatbench uses checked (``path``
    text, ``size`` a byte count, ``lfs`` an object whose ``oid``/``sha256`` is a hex sha256); a
    `transfer.DownloadError` naming the listing, the entry and the field otherwise."""
    entries = {}
    for index, entry in enumerate(listing):
        if not isinstance(entry, dict) or entry.get("type") != "file":
            continue
        path, size, lfs = entry.get("path"), entry.get("size"), entry.get("lfs")
        where = f"{url}: entry {index} ({path!r})"
        if not isinstance(path, str):
            raise transfer.DownloadError(
                f"{where}: key 'path': expected text, found {type(path).__name__}"
            )
        if size is not None and (type(size) is not int or size < 0):
            raise transfer.DownloadError(
                f"{where}: key 'size': expected a byte count, found {size!r:.40}"
            )
        if lfs is not None and not isinstance(lfs, dict):
            raise transfer.DownloadError(
                f"{where}: key 'lfs': expected an object, found {type(lfs).__name__}"
            )
        for key in ("oid", "sha256"):
            value = (lfs or {}).get(key)
            if value is not None and not (
                isinstance(value, str) and re.fullmatch(r"[0-9a-f]{64}", value)
            ):
                raise transfer.DownloadError(
                    f"{where}: key 'lfs.{key}': expected a hex sha256, found {value!r:.80}"
                )
        entries[path] = entry
    return entries


def _matches(path: str, pattern: str) -> bool:
    """Whether ``path`` matches the glob ``pattern`` folder by folder
    (``*`` never crosses a ``/``)."""
    parts, globs = path.split("/"), pattern.split("/")
    return len(parts) == len(globs) and all(
        fnmatch.fnmatchcase(p, g) for p, g in zip(parts, globs, strict=True)
    )


def _one_archive(source: Source, files: list[RemoteFile]) -> list[RemoteFile]:
    """``files`` if they are one archive or the numbered parts (.001, .002, …) of one; otherwise an
    error."""
    files = sorted(files, key=lambda f: f.name)
    stems = {_ARCHIVE.sub(r".\1", f.name) for f in files}
    if len(files) > 1 and (len(stems) > 1 or not all(_PART.search(f.name) for f in files)):
        raise transfer.DownloadError(
            f"{source.name}: several archives match ({', '.join(f.name for f in files)}); "
            "expected one archive or the numbered parts of one"
        )
    return files


def _fetch_verified(
    remote: RemoteFile, folder: Path, recorded: str | None, known_path: Path, key: str, progress
) -> str:
    """Download one file (resuming) and check it against the published sha256, else the one recorded
    the first time a scene was installed from this source (``known_path``, entry ``key``)."""
    target = folder / remote.name
    if not target.exists():
        transfer.download(
            remote.url,
            target,
            expected_size=remote.size,
            progress=progress,
            headers=hub_headers() if remote.hub else None,
        )
    digest = manifest.sha256_file(target)
    expected = remote.sha256 or recorded
    if expected and digest != expected:
        bad = target.with_name(target.name + ".mismatch")
        target.replace(bad)
        if remote.sha256:
            hint = "rerun to download it again"
        else:
            hint = (
                f"the hash was recorded in {known_path} (entry '{key}') when a scene was first "
                "installed from this source; if the source has really changed its file, delete "
                "that entry and rerun"
            )
        raise manifest.IntegrityError(
            f"{remote.name}: sha256 mismatch: expected {expected}, got {digest} "
            f"(kept as {bad} for inspection; {hint})"
        )
    return digest


def _known_hashes(root: Path) -> dict[str, str]:
    """{``<source>/<file>``: sha256} recorded in ``root/.olatbench-sources.json``
    (empty when there is none)."""
    path = root / KNOWN_HASHES
    if not present(path):
        return {}
    try:
        known = parse_json(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:  # UnicodeDecodeError included
        raise DatasetError(
            f"unreadable record of archive hashes ({error}); repair it, or delete it to record "
            "the hashes afresh at the next download",
            path=path,
        ) from None
    if not isinstance(known, dict) or not all(isinstance(value, str) for value in known.values()):
        raise DatasetError("expected a JSON object of archive hashes (text values)", path=path)
    return known


def _record_hashes(root: Path, source: Source, recorded: dict[str, str]) -> None:
    """Add the hashes of archives that unpacked into a valid scene to
    ``root/.olatbench-sources.json``."""
    known = _known_hashes(root)
    known.update({f"{source.name}/{name}": digest for name, digest in recorded.items()})
    write_json(root / KNOWN_HASHES, known)


def _fetch_all(
    source: Source, files: list[RemoteFile], root: Path, label: str, jobs: int, progress: bool
) -> dict[str, str]:
    """Download and verify ``files`` into ``root/.downloads/<source>``; return {file name: sha256}.

    Hashes of files the host does not publish are checked against ``root/.olatbench-sources.json``
    (key ``<source>/<file>``), where `_install` records them once their archive has unpacked into a
    valid scene: a damaged first download is never taken as the reference.
    """
    from olatbench.progress import progress_bar

    known = _known_hashes(root)
    cache = root / DOWNLOADS / source.name
    cache.mkdir(parents=True, exist_ok=True)
    total = sum(f.size for f in files if f.size) or None

    def fetch(remote: RemoteFile) -> str:
        key = f"{source.name}/{remote.name}"
        return _fetch_verified(remote, cache, known.get(key), root / KNOWN_HASHES, key, bar)

    with (
        progress_bar(
            total=total, unit="B", unit_scale=True, desc=label, disable=not progress
        ) as bar,
        ThreadPoolExecutor(max_workers=max(1, jobs)) as pool,
    ):
        digests = list(pool.map(fetch, files))
    return {f.name: d for f, d in zip(files, digests, strict=True)}


def _scene_folder(unpacked: Path) -> Path:
    """The folder of the scene inside an unpacked archive: a lone top-level folder, or the root."""
    entries = [p for p in unpacked.iterdir() if not p.name.startswith(("__MACOSX", "."))]
    return entries[0] if len(entries) == 1 and entries[0].is_dir() else unpacked


class FolderInTheWay(RuntimeError):
    """``ROOT/<scene>`` exists but olatbench did not write it (no manifest): it is left untouched,
    and the message says how to replace it."""


def _replace_command(
    suite: str, scene: str, root: Path, source: str | None, mirror: str | None
) -> str:
    """The ``olatbench datasets download`` command that fetches this one scene again."""
    words = [
        "olatbench",
        "datasets",
        "download",
        suite,
        "--scenes",
        scene,
        "--data-root",
        str(root),
    ]
    words += ["--source", source] if source else []
    words += ["--mirror", mirror] if mirror else []
    return shlex.join(words)


def _refuse_foreign(destination: Path, command: str) -> None:
    """Raise `FolderInTheWay` when ``destination`` holds something olatbench did not download."""
    if not (destination / manifest.MANIFEST_NAME).is_file():
        raise FolderInTheWay(
            f"{destination} exists and was not downloaded by olatbench (no "
            f"{manifest.MANIFEST_NAME}); it was left untouched. If it is a copy of the scene you "
            "made yourself, olatbench run uses it as it is. To replace it with a download, move "
            f"it away first: mv {shlex.quote(str(destination))} "
            f"{shlex.quote(str(destination) + '.mine')} && {command}"
        )


def _set_aside(destination: Path) -> Path:
    """Rename ``destination`` to ``<name>.replaced-<UTC time>`` beside it (never over anything) and
    return that."""
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    aside = destination.with_name(f"{destination.name}.replaced-{stamp}")
    counter = 1
    while present(aside):
        counter += 1
        aside = destination.with_name(f"{destination.name}.replaced-{stamp}-{counter}")
    destination.rename(aside)
    return aside


def _out_of_the_cache(cache: Path, files: list[RemoteFile], archive: Path, problem: str) -> str:
    """Move the downloaded files of an archive that failed (cannot be read or unpacked safely, or is
    no valid scene) out of the cache to ``<name>.damaged``, so that a rerun downloads them again;
    ``problem`` plus where they went and what next."""
    moved = []
    for path in sorted({archive, *(cache / f.name for f in files)}):
        if path.exists():
            path.replace(path.with_name(path.name + ".damaged"))
            moved.append(path.name + ".damaged")
    published = all(f.sha256 for f in files)
    hint = (
        "its sha256 is the one the host publishes, so the host's copy itself is at fault: try "
        "another --source"
        if published
        else "rerun to download it again (fix the mirror first if it serves this file)"
    )
    return f"{problem}; moved to {cache}/{{{','.join(moved)}}}; {hint}"


def download_scene(
    suite: str,
    scene: str,
    root: Path,
    *,
    source: str | None = None,
    mirror: str | None = None,
    jobs: int = 4,
    progress: bool = True,
    notify: Callable[[str], None] | None = None,
) -> Path:
    """Fetch one scene into ``root/<scene>`` (canonical name) and return that folder.

    Sources are tried in order (`sources_for`); one that needs a manual step or cannot be downloaded
    passes to the next, and the error lists why each failed. An intact earlier download is kept.
    Archives are checked against published hashes or against the hash recorded the first time one
    unpacked into a valid scene (``root/.olatbench-sources.json``); a mismatch stops at once.
    Unpacking happens in a temporary folder renamed into place only after the scene validates, so no
    half-unpacked scene is ever left.

    Nothing olatbench did not write is deleted: a ``root/<scene>`` without olatbench's manifest
    stops the download (`FolderInTheWay`, saying how to replace it); one that differs from its
    manifest (damaged or edited) is renamed to ``<scene>.replaced-<time>`` once the new copy is
    ready, and ``notify`` (default: a warning) is told where it went.
    """
    root = Path(root)
    destination = root / scene
    command = _replace_command(suite, scene, root, source, mirror)
    if present(destination):
        if not manifest.verify_folder(destination):
            return destination
        _refuse_foreign(destination, command)
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
            return _install(
                suite,
                scene,
                candidate,
                files,
                recorded,
                root,
                command,
                notify or (lambda message: warnings.warn(message, stacklevel=3)),
            )
    failure = ManualStepRequired if manual_only else transfer.DownloadError
    raise failure(f"{suite}/{scene}: no source could be used:\n" + "\n".join(errors))


def _install(
    suite: str,
    scene: str,
    source: Source,
    files: list[RemoteFile],
    recorded: dict[str, str],
    root: Path,
    command: str,
    notify: Callable[[str], None],
) -> Path:
    """Join the parts, unpack, validate and rename the scene into ``root/<scene>``; record the
    archives' hashes."""
    from olatbench.datasets.validate import validate_folder

    cache = root / DOWNLOADS / source.name
    destination = root / scene
    archive = cache / files[0].name
    if len(files) > 1:
        archive = archives.join_parts(
            [cache / f.name for f in files], cache / _ARCHIVE.sub(r".\1", files[0].name)
        )
    with tempfile.TemporaryDirectory(prefix=f".unpack-{scene}-", dir=root) as temporary:
        unpacked = Path(temporary) / "content"
        try:
            archives.extract(archive, unpacked)
        # the archive's fault: set aside, so a rerun refetches
        except (ArchiveError, UnsafeArchiveError) as error:
            raise type(error)(_out_of_the_cache(cache, files, archive, str(error))) from None
        folder = _scene_folder(unpacked)
        # a tree that is not a valid scene is refused before it is put in place
        report = validate_folder(folder)
        if not report.ok:
            first = "; ".join(
                f"{issue.message} ({issue.path or ''} {issue.frame or ''})".strip()
                for issue in report.errors[:3]
            )
            raise DatasetError(
                _out_of_the_cache(
                    cache,
                    files,
                    archive,
                    f"{suite}/{scene}: the unpacked archive is not a valid scene: {first}",
                ),
                path=archive,
            )
        manifest.write_manifest(folder, source.name, recorded)
        if present(destination):
            _refuse_foreign(destination, command)  # made while the archive downloaded
            aside = _set_aside(destination)
            notify(
                f"{suite}/{scene}: the earlier {destination} differed from its manifest (damaged "
                f"or edited); it was moved to {aside}, nothing in it was deleted"
            )
        folder.rename(destination)
    _record_hashes(root, source, recorded)
    return destination
