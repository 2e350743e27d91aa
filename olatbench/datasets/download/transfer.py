"""Resumable downloads over HTTP(S) range requests (and ``file://`` for local mirrors)."""

from __future__ import annotations

import http.client
import re
import shutil
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from olatbench.datasets.jsontext import parse_json

CHUNK = 1 << 20
USER_AGENT = "olatbench-downloader/1"
MAX_PAGES = 10_000  # a listing that never ends is an error, not a hang
_NEXT_LINK = re.compile(r'<([^>]+)>\s*;\s*rel="?next"?')

Headers = dict[str, str]


class DownloadError(OSError):
    """A download that failed after its retries; names the URL and the partial file kept for
    resuming."""


def _open(url: str, start: int = 0, timeout: float = 30.0, headers: Headers | None = None):
    """Open ``url``; ``headers`` (e.g. ``Authorization``) go to this host only, never to one it
    redirects to."""
    request = urllib.request.Request(url, headers={"User-Agent": USER_AGENT})
    for name, value in (headers or {}).items():
        request.add_unredirected_header(name, value)
    if start:
        request.add_header("Range", f"bytes={start}-")
    return urllib.request.urlopen(request, timeout=timeout)


def next_link(value: str | None) -> str | None:
    """The ``rel="next"`` URL of an HTTP ``Link`` header (RFC 8288), or None."""
    match = _NEXT_LINK.search(value or "")
    return match.group(1) if match else None


def fetch_text(url: str, timeout: float = 30.0, headers: Headers | None = None) -> str:
    """GET a text document (UTF-8), e.g. an HTML index page."""
    try:
        with _open(url, timeout=timeout, headers=headers) as response:
            return response.read().decode("utf-8")
    except (urllib.error.URLError, OSError, UnicodeDecodeError) as error:
        raise DownloadError(f"{url}: cannot read ({error})") from error


def fetch_json(url: str, timeout: float = 30.0, headers: Headers | None = None) -> object:
    """GET a JSON document."""
    return _fetch_page(url, timeout, headers)[0]


def _fetch_page(url: str, timeout: float, headers: Headers | None) -> tuple[object, str | None]:
    """(JSON document, URL of the next page from the ``Link`` header or None)."""
    try:
        with _open(url, timeout=timeout, headers=headers) as response:
            return parse_json(response.read().decode("utf-8")), next_link(
                response.headers.get("Link")
            )
    # ValueError: not UTF-8, not JSON, too deep
    except (urllib.error.URLError, OSError, ValueError) as error:
        raise DownloadError(f"{url}: cannot read JSON ({error})") from error


def fetch_json_pages(url: str, timeout: float = 30.0, headers: Headers | None = None) -> list:
    """GET a paginated JSON list: every page's items, following ``Link: <...>; rel="next"`` until
    none is left (the Hugging Face Hub's tree and commit listings are paginated so)."""
    items: list = []
    page_url: str | None = url
    for _ in range(MAX_PAGES):
        page, next_url = _fetch_page(page_url, timeout, headers)
        if not isinstance(page, list):
            raise DownloadError(f"{page_url}: expected a JSON list, found {type(page).__name__}")
        items += page
        if next_url is None:
            return items
        page_url = urllib.parse.urljoin(page_url, next_url)
    raise DownloadError(f"{url}: more than {MAX_PAGES} pages; stopping")


def _copy_local(url: str, target: Path, partial: Path, expected_size: int | None, progress) -> Path:
    """Copy a ``file://`` URL to ``partial``, check its size (``expected_size``, else the source's)
    and rename it onto ``target``."""
    source = Path(urllib.request.url2pathname(urllib.parse.urlparse(url).path))
    if not source.is_file():
        raise DownloadError(f"{url}: no such file in the mirror folder")
    try:
        expected = source.stat().st_size if expected_size is None else expected_size
        shutil.copyfile(source, partial)
        size = partial.stat().st_size
    except OSError as error:
        raise DownloadError(f"{url}: cannot copy from the mirror folder ({error})") from error
    if size != expected:
        raise DownloadError(
            f"{url}: copied {size} bytes, expected {expected} (the mirror's file changed while it "
            f"was copied?); the partial copy {partial} is replaced by the next run"
        )
    if progress is not None:
        progress.update(size)
    partial.replace(target)
    return target


def download(
    url: str,
    target: Path,
    *,
    expected_size: int | None = None,
    retries: int = 5,
    progress=None,
    timeout: float = 30.0,
    backoff: float = 0.5,
    headers: Headers | None = None,
) -> Path:
    """Download ``url`` to ``target``, resuming from ``target.with_suffix(+'.part')``.

    Each retry asks for the remaining bytes with a ``Range`` header; a server that ignores it
    (status 200) restarts the file. ``progress`` is a tqdm-like object updated with byte counts.
    ``headers`` are sent to ``url``'s host only (not across redirects). The finished file is renamed
    onto ``target`` once it has its full size; the ``.part`` file survives failures. A ``file://``
    URL (a local mirror) is copied to the ``.part`` file the same way, so a copy cut off mid-way
    never lies under ``target``'s name.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(target.name + ".part")
    if urllib.parse.urlparse(url).scheme == "file":
        return _copy_local(url, target, partial, expected_size, progress)
    last_error: Exception | None = None
    for attempt in range(retries + 1):
        start = partial.stat().st_size if partial.exists() else 0
        if expected_size is not None and start == expected_size:
            break
        try:
            with _open(url, start, timeout, headers) as response:
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
            last_error = DownloadError(
                f"{url}: connection closed at {partial.stat().st_size} of {expected_size} bytes"
            )
        except urllib.error.HTTPError as error:
            if error.code == 416 and expected_size is None:  # range past the end: already complete
                break
            if 400 <= error.code < 500 and error.code not in (408, 429):
                raise DownloadError(f"{url}: HTTP {error.code} {error.reason}") from error
            last_error = error
        except (urllib.error.URLError, http.client.HTTPException, OSError) as error:
            last_error = error
        time.sleep(backoff * (2**attempt))
    else:
        raise DownloadError(
            f"{url}: failed after {retries + 1} attempts ({last_error}); "
            f"the partial file {partial} is kept and the next run resumes it"
        )
    size = partial.stat().st_size if partial.exists() else 0
    if expected_size is not None and size != expected_size:
        raise DownloadError(
            f"{url}: got {size} bytes, expected {expected_size}; partial file kept at {partial}"
        )
    partial.replace(target)
    return target
