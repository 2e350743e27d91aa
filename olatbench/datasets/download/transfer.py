"""Resumable downloads over HTTP(S) range requests (and ``file://`` for local mirrors)."""

from __future__ import annotations

import http.client
import json
import shutil
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

CHUNK = 1 << 20
USER_AGENT = "olatbench-downloader/1"


class DownloadError(OSError):
    """A download that failed after its retries; names the URL and the partial file kept for resuming."""


def _open(url: str, start: int = 0, timeout: float = 30.0):
    request = urllib.request.Request(url, headers={"User-Agent": USER_AGENT})
    if start:
        request.add_header("Range", f"bytes={start}-")
    return urllib.request.urlopen(request, timeout=timeout)


def fetch_json(url: str, timeout: float = 30.0) -> object:
    """GET a JSON document."""
    try:
        with _open(url, timeout=timeout) as response:
            return json.loads(response.read().decode("utf-8"))
    except (urllib.error.URLError, OSError, json.JSONDecodeError) as error:
        raise DownloadError(f"{url}: cannot read JSON ({error})") from error


def download(url: str, target: Path, *, expected_size: int | None = None, retries: int = 5,
             progress=None, timeout: float = 30.0, backoff: float = 0.5) -> Path:
    """Download ``url`` to ``target``, resuming from ``target.with_suffix(+'.part')``.

    Each retry asks for the remaining bytes with a ``Range`` header; a server that ignores it
    (status 200) restarts the file. ``progress`` is a tqdm-like object updated with byte counts.
    The finished file is renamed onto ``target``; the ``.part`` file survives failures.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    if urllib.parse.urlparse(url).scheme == "file":
        source = Path(urllib.request.url2pathname(urllib.parse.urlparse(url).path))
        if not source.is_file():
            raise DownloadError(f"{url}: no such file in the mirror folder")
        shutil.copyfile(source, target)
        if progress is not None:
            progress.update(target.stat().st_size)
        return target
    partial = target.with_name(target.name + ".part")
    last_error: Exception | None = None
    for attempt in range(retries + 1):
        start = partial.stat().st_size if partial.exists() else 0
        if expected_size is not None and start == expected_size:
            break
        try:
            with _open(url, start, timeout) as response:
                if start and response.status != 206:
                    start = 0  # the server ignored the range: start over
                with open(partial, "ab" if start else "wb") as handle:
                    if progress is not None and start:
                        progress.update(0)
                    while block := response.read(CHUNK):
                        handle.write(block)
                        if progress is not None:
                            progress.update(len(block))
            if expected_size is None or partial.stat().st_size >= expected_size:
                break
            last_error = DownloadError(f"{url}: connection closed at {partial.stat().st_size} of {expected_size} bytes")
        except urllib.error.HTTPError as error:
            if error.code == 416 and expected_size is None:  # range past the end: already complete
                break
            if 400 <= error.code < 500 and error.code not in (408, 429):
                raise DownloadError(f"{url}: HTTP {error.code} {error.reason}") from error
            last_error = error
        except (urllib.error.URLError, http.client.HTTPException, OSError) as error:
            last_error = error
        time.sleep(backoff * (2 ** attempt))
    else:
        raise DownloadError(f"{url}: failed after {retries + 1} attempts ({last_error}); "
                            f"the partial file {partial} is kept and the next run resumes it")
    size = partial.stat().st_size if partial.exists() else 0
    if expected_size is not None and size != expected_size:
        raise DownloadError(f"{url}: got {size} bytes, expected {expected_size}; partial file kept at {partial}")
    partial.replace(target)
    return target
