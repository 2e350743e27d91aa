"""The viewer's latency in a real browser: from a user's light move to the new image painted on the
page.

What: ``olatbench view JOB`` runs as a subprocess (``--host 127.0.0.1``, a free port), a Chromium
(Debian's ``chromium``; headless with software WebGL by default, ``--headed`` for a real display and
GPU) opens it, and the script drives the page over the Chrome DevTools Protocol
(a websocket on 127.0.0.1). It makes ``--moves`` light moves the way a user does: the left mouse
button is pressed on the thumb of the *azimuth °* slider in the GUI panel and held; each move is one
``mousemove`` of ``--degrees`` along the track (back and forth), followed by stillness until the
full-resolution image is painted and no new image has come for ``--quiet`` seconds.

How: before the page loads, a script (``Page.addScriptToEvaluateOnNewDocument``) instruments it, all
in the page's own clock (``performance.now()``): the move's ``mousemove`` (its ``event.timeStamp``,
t = 0); the slider's value leaving for the server (viser's ``GuiUpdateMessage`` posted to its
websocket worker); each ``BackgroundImageMessage`` reaching the page's main thread from that worker
("arrives": after the websocket, decompression and viser's pacing); its JPEG handed to the image
decoder (viser does so in its render loop), decoded, and uploaded to WebGL as the background texture
(``texImage2D`` / ``texSubImage2D`` with that very image element: inside the frame that draws it).
"Painted" is the end of that frame's task: a ``MessageChannel`` message posted at the upload runs
once the frame's rendering work on the main thread is done and the frame has gone to the compositor.
The GPU process then executes its WebGL commands and the display shows it at its next refresh; that
is not seen from the page, so the time the next animation frame's callbacks run is reported too
(Chromium begins a frame once the previous one is accepted: an upper estimate of when the image is
shown). Reported per move: input -> value sent, -> first new image arrives / painted (the first of
the move's images to be painted: normally the server's reduced-resolution preview), ->
full-resolution image arrives / painted (rendered once the light has been still for the viewer's
settle time, 0.25 s). Full resolution is what the viewer's status line calls ``(full)`` after the
page's first render.

Checks, so that no latency is reported for nothing: each move must change the slider's value and the
full-resolution image (the JPEGs before and after the move are decoded and compared; the same render
twice gives identical bytes), and the image must have been uploaded to WebGL. Moves that fail are
reported and left out. A screenshot of the canvas (left of the GUI panel) is compared with the
previous one as well ("screen diff").

Ends with one ``SUMMARY bench_viewer_browser key=value ...`` line (medians, min and max in ms).

Usage: ``python benchmarks/bench_viewer_browser.py JOB_FOLDER [--moves 10] [--degrees 30] [--headed]
[--json OUT]`` (needs Debian's ``chromium``: ``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import os
import re
import shlex
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from contextlib import suppress
from pathlib import Path
from typing import Any

import cv2
import numpy as np

HOST = "127.0.0.1"
HEADLESS_FLAGS = ["--headless", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
# No traffic but to 127.0.0.1: every other host name fails to resolve; no background services, no
# first-run UI.
CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-breakpad",
    "--disable-crash-reporter",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-extensions",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-default-apps",
    "--no-pings",
    "--disable-domain-reliability",
    f"--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE {HOST}",
]

# Runs in the page before viser's own code (see the module docstring). Times are performance.now()
# milliseconds.
INSTRUMENT = r"""
(() => {
  if (window.__olatLatency) return;
  const now = () => performance.now();
  const L = window.__olatLatency = {inputs: [], sends: [], images: []};
  const byUrl = new Map(), byImage = new WeakMap(), workers = new WeakSet();
  addEventListener('mousemove', (e) => {
    if (e.buttons & 1) L.inputs.push({t: e.timeStamp, handled: now(), x: e.clientX});
  }, true);
  // viser talks to its server from a Worker: see what it posts (GUI updates) and what it hands back (messages).
  const nativePost = Worker.prototype.postMessage;
  Worker.prototype.postMessage = function (data, ...rest) {
    if (!workers.has(this)) {
      workers.add(this);
      this.addEventListener('message', (event) => {
        const d = event.data;
        if (!d || d.type !== 'message_batch') return;
        const t = now();
        for (const m of d.messages) {
          if (m.type !== 'BackgroundImageMessage' || !m.rgb_data) continue;
          L.images.push({index: L.images.length, arrived: t, bytes: m.rgb_data.byteLength, data: m.rgb_data});
          if (L.images.length > 8) delete L.images[L.images.length - 9].data;  // keep the newest JPEGs only
        }
      });
    }
    if (data && data.type === 'send' && data.message && data.message.type === 'GuiUpdateMessage')
      L.sends.push({t: now(), uuid: data.message.uuid, value: (data.message.updates || {}).value});
    return nativePost.call(this, data, ...rest);
  };
  // The JPEG goes to a Blob URL, an <img> decodes it, three.js uploads that <img> as the background texture.
  const nativeCreate = URL.createObjectURL;
  URL.createObjectURL = function (object) {
    const url = nativeCreate.call(URL, object);
    if (object instanceof Blob && object.type.startsWith('image/')) {
      const rec = L.images.find((r) => r.url === undefined && r.bytes === object.size);
      if (rec) { rec.url = url; rec.queued = now(); byUrl.set(url, rec); }
    }
    return url;
  };
  const src = Object.getOwnPropertyDescriptor(HTMLImageElement.prototype, 'src');
  Object.defineProperty(HTMLImageElement.prototype, 'src', {
    configurable: true, enumerable: src.enumerable, get() { return src.get.call(this); },
    set(value) {
      const rec = byUrl.get(value);
      if (rec) {
        byImage.set(this, rec);
        this.addEventListener('load', () => {
          rec.decoded = now(); rec.width = this.naturalWidth; rec.height = this.naturalHeight;
        }, {once: true});
      }
      src.set.call(this, value);
    },
  });
  const hook = (proto, name) => {
    const native = proto[name];
    proto[name] = function (...args) {
      for (const a of args) {
        const rec = a && typeof a === 'object' ? byImage.get(a) : undefined;
        if (rec === undefined || rec.uploaded !== undefined) continue;
        rec.uploaded = now();
        const channel = new MessageChannel();  // runs once this frame's rendering task is over
        channel.port1.onmessage = () => { rec.painted = now(); channel.port1.close(); };
        channel.port2.postMessage(0);
        requestAnimationFrame(() => { rec.nextFrame = now(); });  // the next frame's callbacks run
      }
      return native.apply(this, args);
    };
  };
  for (const cls of [window.WebGLRenderingContext, window.WebGL2RenderingContext])
    if (cls) for (const name of ['texImage2D', 'texSubImage2D']) hook(cls.prototype, name);
  // Resolves once an image arrived at or after t0 (of height `height`, when given) has been painted, and no image
  // has arrived for `quiet` ms since the newest one was painted; false after `timeout` ms.
  L.settled = (t0, height, quiet, timeout) => new Promise((resolve) => {
    const start = now();
    const timer = setInterval(() => {
      const last = L.images[L.images.length - 1];
      const done = L.images.some((r) => r.arrived >= t0 && r.painted !== undefined
                                        && (height === null || r.height === height));
      if (done && last.painted !== undefined && now() - last.arrived >= quiet) {
        clearInterval(timer); resolve(true);
      } else if (now() - start > timeout) { clearInterval(timer); resolve(false); }
    }, 20);
  });
  L.view = (from) => JSON.stringify({
    inputs: L.inputs.filter((r) => r.handled >= from), sends: L.sends.filter((r) => r.t >= from),
    images: L.images.filter((r) => r.arrived >= from).map(({data, ...r}) => r)});
  L.jpeg = (index) => {
    const data = L.images[index].data;
    let text = '';
    for (let i = 0; i < data.length; i += 0x8000) text += String.fromCharCode.apply(null, data.subarray(i, i + 0x8000));
    return btoa(text);
  };
})();
"""  # noqa: E501

# The azimuth slider: its thumb, track and value; the GUI panel's left edge; the status line.
PAGE_STATE = r"""
(() => {
  const thumbs = [...document.querySelectorAll('[role=slider]')];
  let thumb = null;
  for (const t of thumbs) {
    let node = t;
    while (node && !(node.textContent.includes('azimuth') && !node.textContent.includes('elevation')))
      node = node.parentElement;
    if (node && node.textContent.includes('azimuth')) { thumb = t; break; }
  }
  const rect = (el) => {
    if (!el) return null;
    const r = el.getBoundingClientRect();
    return [r.x, r.y, r.width, r.height];
  };
  const track = thumb && thumb.closest('.mantine-Slider-track');
  let panel = null;  // the outermost paper around the slider: the GUI panel
  for (let node = thumb; node; node = node.parentElement) if (node.matches('.mantine-Paper-root')) panel = node;
  const canvas = document.querySelector('canvas');
  const text = document.body ? document.body.innerText : '';
  const status = (text.match(/(\d+)\u00d7(\d+) \((full|dragging)\)/) || []).slice(1);
  return JSON.stringify({thumb: rect(thumb), track: rect(track), panel: rect(panel), canvas: rect(canvas),
    value: thumb ? Number(thumb.getAttribute('aria-valuenow')) : null,
    min: thumb ? Number(thumb.getAttribute('aria-valuemin')) : null,
    max: thumb ? Number(thumb.getAttribute('aria-valuemax')) : null,
    status, webgl_unavailable: text.includes('WebGL unavailable'),
    visibility: document.visibilityState});
})()
"""  # noqa: E501

# The WebGL renderer of viser's own canvas (getContext returns the context three.js made: no new
# context).
RENDERER = r"""
(() => {
  const gl = document.querySelector('canvas').getContext('webgl2');
  if (!gl) return null;
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
})()
"""


class BenchError(RuntimeError):
    """A failure worth one line (no traceback)."""


class DevTools:
    """A minimal Chrome DevTools Protocol client over one page target's websocket."""

    def __init__(self, socket: Any) -> None:
        self.socket = socket
        self.next_id = 0
        self.pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self.exceptions: list[str] = []
        self.reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        closed: BaseException = BenchError("the DevTools connection to chromium closed")
        try:
            async for raw in self.socket:
                message = json.loads(raw)
                future = self.pending.pop(message.get("id", -1), None)
                if future is not None and not future.done():
                    future.set_result(message)
                elif message.get("method") == "Runtime.exceptionThrown":
                    details = message["params"]["exceptionDetails"]
                    self.exceptions.append(
                        str(details.get("exception", {}).get("description", details.get("text")))
                    )
        except asyncio.CancelledError:
            closed = asyncio.CancelledError()
            raise
        finally:
            for future in self.pending.values():
                if not future.done():
                    future.set_exception(closed)

    async def call(self, method: str, timeout: float = 60.0, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        future: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self.pending[self.next_id] = future
        await self.socket.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        message = await asyncio.wait_for(future, timeout)
        if "error" in message:
            raise BenchError(f"DevTools {method}: {message['error'].get('message')}")
        return message.get("result", {})

    async def evaluate(
        self, expression: str, timeout: float = 60.0, await_promise: bool = False
    ) -> Any:
        result = await self.call(
            "Runtime.evaluate",
            timeout=timeout,
            expression=expression,
            returnByValue=True,
            awaitPromise=await_promise,
        )
        if "exceptionDetails" in result:
            raise BenchError(
                f"page script failed: {result['exceptionDetails'].get('text')} "
                f"{result['exceptionDetails'].get('exception', {}).get('description', '')}"
            )
        return result["result"].get("value")

    async def mouse(self, kind: str, x: float, y: float, buttons: int) -> None:
        await self.call(
            "Input.dispatchMouseEvent",
            type=kind,
            x=x,
            y=y,
            button="left",
            buttons=buttons,
            clickCount=1 if kind != "mouseMoved" else 0,
        )

    async def screenshot(self, clip: tuple[float, float, float, float]) -> np.ndarray:
        """A (H, W, 3) uint8 BGR screenshot of ``clip`` (x, y, width, height in CSS pixels)."""
        x, y, width, height = clip
        result = await self.call(
            "Page.captureScreenshot",
            format="png",
            clip={"x": x, "y": y, "width": width, "height": height, "scale": 1},
        )
        return cv2.imdecode(
            np.frombuffer(base64.b64decode(result["data"]), np.uint8), cv2.IMREAD_COLOR
        )


class Processes:
    """The viewer and the browser, each in its own process group, ended together
    (also on Ctrl-C and errors)."""

    def __init__(self) -> None:
        self.started: list[subprocess.Popen[bytes]] = []
        self.temp = Path(tempfile.mkdtemp(prefix="bench_viewer_browser-"))

    def start(self, command: list[str], log: str, **kwargs: Any) -> subprocess.Popen[bytes]:
        with open(self.temp / log, "wb") as out:
            process = subprocess.Popen(
                command,
                stdout=out,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
                **kwargs,
            )
        self.started.append(process)
        return process

    def log_tail(self, log: str, lines: int = 15) -> str:
        path = self.temp / log
        return (
            "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
            if path.exists()
            else ""
        )

    def close(self) -> None:
        for process in reversed(self.started):
            if process.poll() is None:
                with suppress(ProcessLookupError):
                    os.killpg(process.pid, signal.SIGINT)  # the viewer stops its server on Ctrl-C
                try:
                    process.wait(5)
                except subprocess.TimeoutExpired:
                    with suppress(ProcessLookupError):
                        os.killpg(process.pid, signal.SIGKILL)
                    process.wait(5)
            # children left in the group (chromium's renderer, GPU process)
            with suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
                for _ in range(50):  # until the group is gone
                    time.sleep(0.1)
                    os.killpg(process.pid, 0)
        shutil.rmtree(self.temp, ignore_errors=True)


def find_chromium(explicit: str | None) -> str:
    for name in [explicit] if explicit else ["chromium", "chromium-browser", "google-chrome"]:
        path = shutil.which(name)
        if path:
            return path
    raise BenchError(
        f"{explicit or 'chromium'} not found: install Debian's chromium (apt-get install chromium) "
        "or pass --chromium PATH"
    )


def wait_for(
    predicate: Any,
    timeout: float,
    what: str,
    process: subprocess.Popen[bytes],
    procs: Processes,
    log: str,
) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = predicate()
        if found:
            return found
        if process.poll() is not None:
            raise BenchError(
                f"{what}: the process exited with {process.returncode}:\n{procs.log_tail(log)}"
            )
        time.sleep(0.1)
    raise BenchError(f"{what}: nothing after {timeout:.0f} s:\n{procs.log_tail(log)}")


def start_viewer(procs: Processes, job: Path, args: argparse.Namespace) -> str:
    """``olatbench view JOB`` on 127.0.0.1 and a free port (viser picks it: port 0); returns its
    URL."""
    command = [
        sys.executable,
        "-m",
        "olatbench",
        "view",
        str(job),
        "--host",
        HOST,
        "--port",
        "0",
        "--drag-scale",
        str(args.drag_scale),
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = procs.start(command, "viewer.log", env=env)

    def url() -> str | None:
        found = re.search(
            r"olatbench view: .* at (http://127\.0\.0\.1:\d+)",
            (procs.temp / "viewer.log").read_text(),
        )
        return found.group(1) if found else None

    return wait_for(
        url, args.startup_timeout, "olatbench view did not start", process, procs, "viewer.log"
    )


def start_chromium(procs: Processes, args: argparse.Namespace) -> str:
    """Chromium on about:blank with a DevTools port (its own pick); returns the page target's
    websocket URL."""
    profile = procs.temp / "profile"
    command = [
        find_chromium(args.chromium),
        *([] if args.headed else HEADLESS_FLAGS),
        *CHROMIUM_FLAGS,
        f"--user-data-dir={profile}",
        f"--window-size={args.window[0]},{args.window[1]}",
        "--remote-debugging-address=127.0.0.1",
        "--remote-debugging-port=0",
        *shlex.split(args.chromium_args),
        "about:blank",
    ]
    process = procs.start(command, "chromium.log")
    active = profile / "DevToolsActivePort"  # chromium writes the port it listens on here
    port = wait_for(
        lambda: active.exists() and (active.read_text().split() or [None])[0],
        60,
        "chromium's DevTools port",
        process,
        procs,
        "chromium.log",
    )

    def page() -> str | None:
        with suppress(OSError, ValueError):
            with urllib.request.urlopen(f"http://{HOST}:{port}/json/list", timeout=5) as response:
                targets = json.load(response)
            return next(
                (t["webSocketDebuggerUrl"] for t in targets if t.get("type") == "page"), None
            )
        return None

    return wait_for(page, 30, "chromium's page target", process, procs, "chromium.log")


def image_difference(old: bytes, new: bytes) -> float:
    """Mean absolute difference (8-bit levels) of two JPEGs of one size."""
    a, b = (
        cv2.imdecode(np.frombuffer(d, np.uint8), cv2.IMREAD_COLOR).astype(np.float64)
        for d in (old, new)
    )
    return float(np.abs(a - b).mean()) if a.shape == b.shape else float("inf")


async def measure(
    devtools: DevTools, url: str, args: argparse.Namespace
) -> tuple[list[dict[str, Any]], dict]:
    """Load the viewer, press on the azimuth thumb, make the moves; (one record per move, page
    facts)."""
    await devtools.call("Page.enable")
    await devtools.call("Runtime.enable")
    await devtools.call("Page.addScriptToEvaluateOnNewDocument", source=INSTRUMENT)
    await devtools.call("Page.navigate", url=url)
    deadline = time.monotonic() + args.startup_timeout
    while True:  # the GUI is up and the first render is on the page at full resolution
        state = json.loads(await devtools.evaluate(PAGE_STATE))
        if state["webgl_unavailable"]:
            raise BenchError(
                "the page has no WebGL in this chromium (headless needs --use-angle=swiftshader "
                "--enable-unsafe-swiftshader; see --chromium-args)"
            )
        if state["thumb"] and state["status"][-1:] == ["full"]:
            break
        if time.monotonic() > deadline:
            raise BenchError(
                "the viewer page did not show a full-resolution render within "
                f"{args.startup_timeout} s"
            )
        await asyncio.sleep(0.25)
    full_height = int(state["status"][1])
    if not await devtools.evaluate(
        f"__olatLatency.settled(0, {full_height}, {1000 * args.quiet}, "
        f"{1000 * args.startup_timeout})",
        timeout=args.startup_timeout + 10,
        await_promise=True,
    ):
        raise BenchError(
            "the first full-resolution image was never painted (is the page's WebGL working?)"
        )
    for _ in range(40):  # the panel's layout has settled: the thumb stays put
        await asyncio.sleep(0.25)
        previous_state, state = state, json.loads(await devtools.evaluate(PAGE_STATE))
        if state["thumb"] == previous_state["thumb"]:
            break
    thumb, track, panel = state["thumb"], state["track"], state["panel"]
    x, y = thumb[0] + thumb[2] / 2, thumb[1] + thumb[3] / 2
    if not await devtools.evaluate(f"document.elementFromPoint({x}, {y}).matches('[role=slider]')"):
        raise BenchError(
            f"the azimuth slider's thumb is not at ({x:.0f}, {y:.0f}) in the page (covered? try "
            "--window)"
        )
    canvas = state["canvas"]
    clip = (
        canvas[0],
        canvas[1],
        max(1.0, (panel[0] if panel else canvas[0] + canvas[2]) - canvas[0]),
        canvas[3],
    )
    mark = await devtools.evaluate("performance.now()")
    # may move the value by a pixel's rounding: wait it out
    await devtools.mouse("mousePressed", x, y, buttons=1)
    await asyncio.sleep(0.2)
    if json.loads(await devtools.evaluate(PAGE_STATE))["value"] != state["value"]:
        await devtools.evaluate(
            f"__olatLatency.settled({mark}, {full_height}, {1000 * args.quiet}, "
            f"{1000 * args.timeout})",
            timeout=args.timeout + 10,
            await_promise=True,
        )
    step = args.degrees / (state["max"] - state["min"]) * track[2]  # CSS pixels per move
    direction = 1.0
    images = json.loads(await devtools.evaluate("__olatLatency.view(0)"))["images"]
    previous = [i for i in images if i.get("height") == full_height][-1]
    previous_jpeg = base64.b64decode(
        await devtools.evaluate(f"__olatLatency.jpeg({previous['index']})")
    )
    shot = await devtools.screenshot(clip)
    facts = {
        "full_height": full_height,
        "status": state["status"],
        "renderer": await devtools.evaluate(RENDERER),
        "canvas": canvas,
        "visibility": state["visibility"],
        "clip": clip,
    }
    records = []
    for move in range(args.moves):
        if not track[0] + 2 <= x + direction * step <= track[0] + track[2] - 2:
            direction = -direction
        value_before = json.loads(await devtools.evaluate(PAGE_STATE))["value"]
        mark = await devtools.evaluate("performance.now()")
        x += direction * step
        await devtools.mouse("mouseMoved", x, y, buttons=1)
        settled = await devtools.evaluate(
            f"__olatLatency.settled({mark}, {full_height}, {1000 * args.quiet}, "
            f"{1000 * args.timeout})",
            timeout=args.timeout + 10,
            await_promise=True,
        )
        view = json.loads(await devtools.evaluate(f"__olatLatency.view({mark})"))
        value_after = json.loads(await devtools.evaluate(PAGE_STATE))["value"]
        record: dict[str, Any] = {
            "move": move + 1,
            "from": value_before,
            "to": value_after,
            "settled": settled,
            "images": len(view["images"]),
            "page": view,
        }
        problems = [] if settled else [f"no full-resolution image painted within {args.timeout} s"]
        if not view["inputs"]:
            problems.append("the page saw no mousemove")
        if value_after == value_before:
            problems.append("the slider's value did not change")
        if view["inputs"] and view["images"]:
            t0 = view["inputs"][0]["t"]
            sends = [s for s in view["sends"] if s["t"] >= t0]
            painted = [i for i in view["images"] if "painted" in i]
            first = min(painted, key=lambda i: i["painted"]) if painted else view["images"][0]
            full = next((i for i in view["images"] if i.get("height") == full_height), None)
            record.update(
                sent=sends[0]["t"] - t0 if sends else None,
                first_size=(first.get("width"), first.get("height")),
                first_kb=first["bytes"] / 1024,
            )
            for stage in ("arrived", "queued", "decoded", "uploaded", "painted", "nextFrame"):
                record[f"first_{stage}"] = first[stage] - t0 if stage in first else None
            if full is not None and "painted" in full:
                record.update(
                    full_size=(full["width"], full["height"]),
                    full_arrived=full["arrived"] - t0,
                    full_painted=full["painted"] - t0,
                    full_nextFrame=full["nextFrame"] - t0 if "nextFrame" in full else None,
                )
                jpeg = base64.b64decode(
                    await devtools.evaluate(f"__olatLatency.jpeg({full['index']})")
                )
                record["image_diff"] = image_difference(previous_jpeg, jpeg)
                if jpeg == previous_jpeg:
                    problems.append("the full-resolution image did not change")
                previous_jpeg = jpeg
            else:
                problems.append("no full-resolution image was painted")
            if record.get("first_painted") is None:
                problems.append("no new image was uploaded to WebGL and painted")
        elif not view["images"]:
            problems.append("no image came")
        new_shot = await devtools.screenshot(clip)
        record["screen_diff"] = (
            float(np.abs(new_shot.astype(np.float64) - shot).mean())
            if new_shot.shape == shot.shape
            else float("inf")
        )
        shot = new_shot
        record["problems"] = problems
        records.append(record)
        print(row(record), flush=True)
        await asyncio.sleep(args.pause)
    await devtools.mouse("mouseReleased", x, y, buttons=0)
    facts["exceptions"] = list(devtools.exceptions)
    return records, facts


COLUMNS = (
    "move",
    "azimuth",
    "sent",
    "1st arrives",
    "1st painted",
    "1st size",
    "full arrives",
    "full painted",
    "full size",
    "image diff",
    "screen diff",
)


def header() -> str:
    return (
        f"{COLUMNS[0]:>4s} {COLUMNS[1]:>13s} {COLUMNS[2]:>6s} {COLUMNS[3]:>11s} {COLUMNS[4]:>11s} "
        f"{COLUMNS[5]:>9s} {COLUMNS[6]:>12s} {COLUMNS[7]:>12s} {COLUMNS[8]:>9s} {COLUMNS[9]:>10s} "
        f"{COLUMNS[10]:>11s}"
    )


def row(r: dict[str, Any]) -> str:
    def ms(key: str, width: int) -> str:
        return f"{r[key]:{width}.1f}" if r.get(key) is not None else f"{'-':>{width}s}"

    def size(key: str) -> str:
        return f"{r[key][0]}x{r[key][1]}" if r.get(key) and r[key][0] else "-"

    azimuth = f"{r['from']:g}->{r['to']:g}"
    text = (
        f"{r['move']:4d} {azimuth:>13s} {ms('sent', 6)} {ms('first_arrived', 11)} "
        f"{ms('first_painted', 11)} {size('first_size'):>9s} {ms('full_arrived', 12)} "
        f"{ms('full_painted', 12)} {size('full_size'):>9s} "
        f"{r.get('image_diff', float('nan')):10.2f} {r['screen_diff']:11.2f}"
    )
    return text + (f"  INVALID: {'; '.join(r['problems'])}" if r["problems"] else "")


def run(args: argparse.Namespace) -> int:
    job = Path(args.job)
    if not job.is_dir():
        raise BenchError(f"{job} is not a folder")
    gaussians = None
    with suppress(OSError, ValueError, KeyError, TypeError):
        gaussians = json.loads((job / "results.json").read_text())["model"]["num_gaussians"]
    find_chromium(args.chromium)  # fail before starting anything
    procs = Processes()
    try:
        load_before = os.getloadavg()
        url = start_viewer(procs, job, args)
        page = start_chromium(procs, args)
        from websockets.asyncio.client import connect

        async def session() -> tuple[list[dict[str, Any]], dict]:
            async with connect(page, max_size=None, open_timeout=30) as socket:
                devtools = DevTools(socket)
                try:
                    version = (await devtools.call("Browser.getVersion"))["product"]
                    print(
                        f"job {job} ({gaussians if gaussians is not None else '?'} Gaussians), "
                        f"viewer {url}, {version}, {'headed' if args.headed else 'headless'}"
                    )
                    print(
                        "per move: ms from the mousemove; image diff: mean |difference| of the "
                        "full-resolution images before and after (8-bit levels); screen diff: of "
                        "the canvas screenshots"
                    )
                    print(header(), flush=True)
                    records, facts = await measure(devtools, url, args)
                    facts["version"] = version
                    return records, facts
                finally:
                    devtools.reader.cancel()

        records, facts = asyncio.run(session())
        load_after = os.getloadavg()
    finally:
        procs.close()
    return report(records, facts, args, load_before, load_after, gaussians)


def report(
    records: list[dict[str, Any]],
    facts: dict,
    args: argparse.Namespace,
    load_before: tuple[float, ...],
    load_after: tuple[float, ...],
    gaussians: int | None,
) -> int:
    if args.json is not None:
        args.json.write_text(json.dumps({"records": records, "facts": facts}, indent=1) + "\n")
    valid = [r for r in records if not r["problems"]]
    print(
        f"WebGL renderer: {facts['renderer']}; page {facts['visibility']}; canvas "
        f"{facts['canvas'][2]:.0f}x{facts['canvas'][3]:.0f} CSS px; full resolution "
        f"{facts['status'][0]}x{facts['status'][1]}; load average {load_before[0]:.1f} before, "
        f"{load_after[0]:.1f} after, on {os.cpu_count()} CPUs"
    )
    image_aspect = int(facts["status"][0]) / int(facts["status"][1])
    canvas_aspect = facts["canvas"][2] / facts["canvas"][3]
    if abs(image_aspect / canvas_aspect - 1) > 0.05:
        print(
            f"warning: the viewer renders at aspect {image_aspect:.2f}, the canvas is "
            f"{canvas_aspect:.2f} (it did not take the canvas's size from the browser's first "
            "camera messages)"
        )
    if facts["exceptions"]:
        print(f"page exceptions: {facts['exceptions'][:3]}")
    if not valid:
        print(f"no valid move of {len(records)}: nothing measured")
        print(f"SUMMARY bench_viewer_browser moves={len(records)} valid=0 status=failed")
        return 1
    print(
        f"\nlatency from the mousemove to ..., ms, over {len(valid)} valid moves of {len(records)} "
        f"({args.degrees:g} deg each):"
    )
    print(f"{'':34s} {'median':>8s} {'min':>8s} {'max':>8s}")
    keys = [
        ("sent", "value sent to the server"),
        ("first_arrived", "first new image arrives"),
        ("first_queued", "  handed to the decoder"),
        ("first_decoded", "  decoded"),
        ("first_uploaded", "  uploaded to WebGL (its frame)"),
        ("first_painted", "first new image painted"),
        ("first_nextFrame", "  next animation frame runs"),
        ("full_arrived", "full-resolution image arrives"),
        ("full_painted", "full-resolution image painted"),
        ("full_nextFrame", "  next animation frame runs"),
    ]
    summary: dict[str, float] = {}
    for key, label in keys:
        values = [r[key] for r in valid if r.get(key) is not None]
        if not values:
            continue
        median = statistics.median(values)
        print(f"{label:34s} {median:8.1f} {min(values):8.1f} {max(values):8.1f}")
        if key in ("sent", "first_arrived", "first_painted", "full_arrived", "full_painted"):
            summary |= {
                f"{key}_ms": median,
                f"{key}_ms_min": min(values),
                f"{key}_ms_max": max(values),
            }
    first = valid[0].get("first_size") or (0, 0)
    full = valid[0].get("full_size") or (0, 0)
    print(
        "SUMMARY bench_viewer_browser "
        + " ".join(f"{k}={v:.1f}" for k, v in summary.items())
        + f" moves={len(records)} valid={len(valid)} degrees={args.degrees:g} "
        f"first={first[0]}x{first[1]} full={full[0]}x{full[1]} "
        f"gaussians={gaussians if gaussians is not None else 'unknown'} "
        f"browser={'headed' if args.headed else 'headless'} load={load_before[0]:.1f}"
    )
    return 0 if len(valid) == len(records) else 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("job", help="a finished job folder (anything `olatbench view` shows)")
    parser.add_argument("--moves", type=int, default=10, help="light moves to time (default 10)")
    parser.add_argument(
        "--degrees", type=float, default=30.0, help="azimuth change of one move (default 30)"
    )
    parser.add_argument(
        "--quiet",
        type=float,
        default=0.6,
        help="seconds without a new image before a move counts as done (default 0.6)",
    )
    parser.add_argument(
        "--pause", type=float, default=0.3, help="extra seconds between moves (default 0.3)"
    )
    parser.add_argument(
        "--timeout", type=float, default=60.0, help="seconds to wait for one move's images"
    )
    parser.add_argument(
        "--startup-timeout",
        type=float,
        default=300.0,
        help="seconds for the viewer to restore the job and show its first image (default 300)",
    )
    parser.add_argument(
        "--drag-scale", type=float, default=0.5, help="passed to olatbench view (default 0.5)"
    )
    parser.add_argument(
        "--window",
        type=int,
        nargs=2,
        default=(1280, 800),
        metavar=("W", "H"),
        help="browser window size (default 1280 800)",
    )
    parser.add_argument("--chromium", help="the browser executable (default: chromium on PATH)")
    parser.add_argument(
        "--headed",
        action="store_true",
        help="a visible window on the real display and GPU instead of headless software WebGL",
    )
    parser.add_argument("--chromium-args", default="", help="extra chromium flags, one string")
    parser.add_argument(
        "--json", type=Path, help="also write every move's page timeline (ms, page clock) here"
    )
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # cleaned up as on Ctrl-C
    try:
        sys.exit(run(args))
    except BenchError as error:
        sys.exit(f"bench_viewer_browser: {error}")
    except KeyboardInterrupt:
        print("bench_viewer_browser: interrupted", file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    main()
