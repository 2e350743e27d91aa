"""A bounded local HTTP server for download tests: range requests, a Hugging Face-like tree API
paginated like the Hub's (``Link: <...?cursor=N>; rel="next"``), and injectable faults
(a connection dropped mid-file). Listens on 127.0.0.1 only."""

from __future__ import annotations

import json
import threading
import urllib.parse
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

MAX_REQUESTS = 200


@dataclass
class ServerState:
    """Files served (URL path -> bytes), the API listings, faults to inject, and a request log."""

    files: dict[str, bytes] = field(default_factory=dict)
    # JSON answers; lists are paged
    listings: dict[str, list[dict] | dict] = field(default_factory=dict)
    # path -> bytes sent before dropping (once)
    drop_after: dict[str, int] = field(default_factory=dict)
    ignore_range: bool = False
    # listings longer than this are served in pages linked by a Link header
    page_size: int | None = None
    requests: list[tuple[str, str | None]] = field(default_factory=list)
    # path, Authorization header
    authorization: list[tuple[str, str | None]] = field(default_factory=list)


def _handler(state: ServerState):
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):  # keep test output quiet
            pass

        def do_GET(self):
            path, _, query = self.path.partition("?")
            state.requests.append((path, self.headers.get("Range")))
            state.authorization.append((path, self.headers.get("Authorization")))
            if len(state.requests) > MAX_REQUESTS:
                self.send_error(429, "request budget of the test server exhausted")
                return
            if path in state.listings:
                items = state.listings[path]
                params = urllib.parse.parse_qs(query)
                start = int(params.get("cursor", ["0"])[0])
                end = (
                    len(items)
                    if state.page_size is None or not isinstance(items, list)
                    else start + state.page_size
                )
                body = json.dumps(items[start:end] if isinstance(items, list) else items).encode()
                self.send_response(200)
                if end < len(items):
                    params["cursor"] = [str(end)]
                    link = f"{path}?{urllib.parse.urlencode(params, doseq=True)}"
                    self.send_header("Link", f'<http://{self.headers["Host"]}{link}>; rel="next"')
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)
                return
            data = state.files.get(path)
            if data is None:
                self.send_error(404)
                return
            start = 0
            requested = self.headers.get("Range")
            if requested and not state.ignore_range:
                start = int(requested.split("=")[1].split("-")[0])
                self.send_response(206)
                self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
            else:
                self.send_response(200)
            body = data[start:]
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            cut = state.drop_after.pop(path, None)
            if cut is not None:
                self.wfile.write(body[:cut])
                self.wfile.flush()
                self.close_connection = True
                return
            self.wfile.write(body)

    return Handler


class LocalServer:
    """Context manager running the server in a thread; ``url`` is its base address."""

    def __init__(self, state: ServerState) -> None:
        self.state = state
        self.server = ThreadingHTTPServer(("127.0.0.1", 0), _handler(state))
        self.server.timeout = 5
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server.server_address[1]}"

    def __enter__(self) -> LocalServer:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.server.shutdown()
        self.server.server_close()
        self.thread.join(timeout=5)


def serve_folder_files(state: ServerState, folder: Path, url_prefix: str = "") -> None:
    """Serve every file of ``folder`` under ``url_prefix/<name>``."""
    for path in folder.iterdir():
        if path.is_file():
            state.files[f"{url_prefix}/{path.name}"] = path.read_bytes()
