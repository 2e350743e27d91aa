"""The viewer's environment-map mode in a real browser: switch to it the way a user does, watch the
refinement, move the camera during it, let it converge, and take a screenshot.

What: ``olatbench view JOB`` runs as a subprocess (127.0.0.1, a free port, ``--samples K``), a
headless Chromium (Debian's ``chromium``, software WebGL; ``--headed`` for a real display) opens it,
and the script drives the page over the Chrome DevTools Protocol with the helpers of
``bench_viewer_browser.py`` beside it: mouse clicks on the *lighting* menu and its *environment map*
option (and on the *map* menu for ``--map``; ``--exposure`` is typed into the exposure box), then it
reads the status line (``studio · 28/64 samples · 512×263 (refining) in 812 ms``) every 0.1 s and
prints each change with its time since the click. With ``--move-after N`` it drags the mouse across
the canvas (viser orbits the camera) once N samples are averaged, and checks that the refinement
starts again (the status goes back to fewer samples, or to ``(moving)``). It waits for
``(converged)`` at ``K/K`` samples and writes a PNG screenshot of the page (``--out``).

Checks (exit 1 and a line saying which failed): the page switched to the environment map, the sample
count grew pass by pass, the camera move restarted the refinement, the view converged to K samples,
and the converged image differs from the point-light image shown before the switch (the JPEGs of the
two, as the page received them).

Usage: ``python benchmarks/viewer_envmap_browser.py JOB_FOLDER --out shot.png [--samples 64]
[--map studio] [--exposure -1] [--zoom-out 3] [--move-after 12] [--window 1100 640]`` (needs
Debian's ``chromium``: ``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import os
import re
import signal
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_viewer_browser import (  # the module beside this one
    HOST,
    INSTRUMENT,
    BenchError,
    DevTools,
    Processes,
    find_chromium,
    image_difference,
    start_chromium,
    wait_for,
)

# The status line's parts: (map, done, total, width, height, state), or the point light's
# (width, height, state).
STATUS = r"""
(() => {
  const text = document.body ? document.body.innerText : '';
  const env = text.match(/([^\n·]+) · (\d+)\/(\d+) samples · (\d+)\u00d7(\d+) \((moving|refining|converged)\)/);
  if (env) return JSON.stringify({map: env[1].trim(), done: +env[2], total: +env[3], width: +env[4],
                                  height: +env[5], state: env[6]});
  const point = text.match(/(\d+)\u00d7(\d+) \((full|dragging)\)/);
  const failed = text.match(/\*\*[^\n]*|render failed[^\n]*|environment map\*?\*?:[^\n]*/);
  return JSON.stringify(point ? {width: +point[1], height: +point[2], state: point[3]}
                              : {state: null, message: failed ? failed[0] : null});
})()
"""  # noqa: E501

# The centre of the input of the visible GUI control labelled LABEL (an element whose own text is
# the label, and the nearest input around it), or null.
CONTROL = r"""
((label) => {
  const own = (el) => [...el.childNodes].filter((n) => n.nodeType === 3).map((n) => n.textContent).join('').trim();
  for (const el of document.querySelectorAll('body *')) {
    if (own(el) !== label) continue;
    for (let node = el; node; node = node.parentElement) {
      const input = node.querySelector('input:not([type=hidden])');
      if (input) {
        const r = input.getBoundingClientRect();
        if (r.width === 0) break;  // a hidden folder's control: not yet shown
        return JSON.stringify([r.x + r.width / 2, r.y + r.height / 2]);
      }
    }
  }
  return null;
})
"""  # noqa: E501

# The centre of the visible dropdown option whose text is TEXT, or null.
OPTION = r"""
((text) => {
  for (const el of document.querySelectorAll('[role=option]')) {
    const r = el.getBoundingClientRect();
    if (el.textContent.trim() === text && r.width > 0) return JSON.stringify([r.x + r.width / 2, r.y + r.height / 2]);
  }
  return null;
})
"""  # noqa: E501

CANVAS = (
    "(() => { const r = document.querySelector('canvas').getBoundingClientRect(); "
    "return JSON.stringify([r.x, r.y, r.width, r.height]); })()"
)


async def click(devtools: DevTools, x: float, y: float) -> None:
    await devtools.mouse("mousePressed", x, y, buttons=1)
    await devtools.mouse("mouseReleased", x, y, buttons=0)


async def status(devtools: DevTools) -> dict[str, Any]:
    return json.loads(await devtools.evaluate(STATUS))


async def until(
    devtools: DevTools, predicate: Any, timeout: float, what: str, poll: float = 0.1
) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = await predicate()
        if found:
            return found
        await asyncio.sleep(poll)
    raise BenchError(f"{what}: not within {timeout:.0f} s (status: {await status(devtools)})")


async def choose(devtools: DevTools, label: str, option: str, timeout: float) -> None:
    """Open the GUI dropdown ``label`` with a click and click its ``option``."""

    async def control() -> Any:
        found = await devtools.evaluate(f"({CONTROL})({json.dumps(label)})")
        return json.loads(found) if found else None

    x, y = await until(devtools, control, timeout, f"the {label!r} menu")
    await click(devtools, x, y)

    async def item() -> Any:
        found = await devtools.evaluate(f"({OPTION})({json.dumps(option)})")
        return json.loads(found) if found else None

    ox, oy = await until(devtools, item, 10, f"the {option!r} option of {label!r}")
    await click(devtools, ox, oy)


async def type_number(devtools: DevTools, label: str, value: float, timeout: float) -> None:
    """Type ``value`` into the number box of the GUI control ``label`` (a slider's box) and press
    Enter."""

    async def control() -> Any:
        found = await devtools.evaluate(f"({CONTROL})({json.dumps(label)})")
        return json.loads(found) if found else None

    x, y = await until(devtools, control, timeout, f"the {label!r} box")
    await devtools.call(
        "Input.dispatchMouseEvent",
        type="mousePressed",
        x=x,
        y=y,
        button="left",
        buttons=1,
        clickCount=3,
    )  # a triple click selects the number
    await devtools.call(
        "Input.dispatchMouseEvent",
        type="mouseReleased",
        x=x,
        y=y,
        button="left",
        buttons=0,
        clickCount=3,
    )
    await devtools.call("Input.insertText", text=f"{value:g}")
    for kind in ("keyDown", "keyUp"):
        await devtools.call(
            "Input.dispatchKeyEvent", type=kind, key="Enter", code="Enter", windowsVirtualKeyCode=13
        )


async def newest_jpeg(devtools: DevTools) -> bytes:
    index = await devtools.evaluate("__olatLatency.images.length - 1")
    return base64.b64decode(await devtools.evaluate(f"__olatLatency.jpeg({index})"))


async def drive(
    devtools: DevTools, url: str, args: argparse.Namespace
) -> tuple[list[dict[str, Any]], list[str]]:
    """(the status changes, each with ``t`` seconds since the switch; the failed checks)."""
    await devtools.call("Page.enable")
    await devtools.call("Runtime.enable")
    # keeps the received JPEGs
    await devtools.call("Page.addScriptToEvaluateOnNewDocument", source=INSTRUMENT)
    await devtools.call("Page.navigate", url=url)

    async def point_full() -> bool:
        return (await status(devtools)).get("state") == "full"

    await until(devtools, point_full, args.startup_timeout, "the first point-light image")
    await asyncio.sleep(1.0)  # the panel's layout settles
    if args.zoom_out:  # mouse-wheel steps on the canvas: viser's camera backs off
        x, y, width, height = json.loads(await devtools.evaluate(CANVAS))
        for _ in range(args.zoom_out):
            await devtools.call(
                "Input.dispatchMouseEvent",
                type="mouseWheel",
                x=x + 0.3 * width,
                y=y + 0.5 * height,
                deltaX=0,
                deltaY=100,
            )
            await asyncio.sleep(0.05)
        await asyncio.sleep(1.0)
        await until(devtools, point_full, args.timeout, "the zoomed-out point-light image")
    point_jpeg = await newest_jpeg(devtools)
    started = time.monotonic()
    await choose(devtools, "lighting", "environment map", 30)
    if args.map != "studio":
        await asyncio.sleep(0.5)  # the lighting menu has closed
        await choose(devtools, "map", args.map, 30)
    if args.exposure:
        await asyncio.sleep(0.5)
        await type_number(devtools, "exposure (stops)", args.exposure, 30)

    async def showing_map() -> bool:
        return (await status(devtools)).get("map") == args.map

    await until(devtools, showing_map, 60, f"the tab showing the map {args.map!r}")
    changes: list[dict[str, Any]] = []
    moved_at: int | None = None
    failures: list[str] = []
    deadline = started + args.timeout
    while time.monotonic() < deadline:
        now = await status(devtools)
        if not changes or {k: v for k, v in now.items() if k != "t"} != {
            k: v for k, v in changes[-1].items() if k != "t"
        }:
            now["t"] = round(time.monotonic() - started, 2)
            changes.append(now)
            print(json.dumps(now), flush=True)
            if now.get("state") is None and now.get("message"):
                failures.append(f"the tab says: {now['message']}")
                break
        one_pass = bool(changes) and [c.get("state") for c in changes if c.get("map") == args.map][
            :1
        ] == ["converged"]
        if one_pass:  # a method that ignores the light (3DGS): one render stands for every sample
            print("converged in one pass: the method ignores the light", flush=True)
            break
        if (
            args.move_after
            and moved_at is None
            and now.get("state") == "refining"
            and now.get("map") == args.map
            and now["done"] >= args.move_after
        ):
            x, y, width, height = json.loads(await devtools.evaluate(CANVAS))
            cx, cy = x + 0.3 * width, y + 0.5 * height
            await devtools.mouse("mousePressed", cx, cy, buttons=1)
            for step in range(1, 6):  # a short drag: viser orbits the camera
                await devtools.mouse("mouseMoved", cx + 8 * step, cy, buttons=1)
                await asyncio.sleep(0.03)
            await devtools.mouse("mouseReleased", cx + 40, cy, buttons=0)
            moved_at = len(changes)
            print(f"dragged the camera at {now['done']}/{now['total']} samples", flush=True)
        if (
            now.get("state") == "converged"
            and now.get("map") == args.map
            and (moved_at or not args.move_after)
        ):
            break
        await asyncio.sleep(0.1)
    env = [c for c in changes if c.get("map") == args.map]
    one_pass = bool(env) and env[0]["state"] == "converged"
    if not env:
        failures.append("the page never showed the environment map")
    elif not one_pass:
        refining = [c["done"] for c in env if c["state"] == "refining"]
        if len(set(refining)) < 2:
            failures.append(f"the samples did not grow pass by pass (refining: {refining})")
        if env[-1]["state"] != "converged" or env[-1]["done"] != args.samples:
            failures.append(f"did not converge to {args.samples} samples: {env[-1]}")
    if args.move_after and not one_pass:
        after = changes[moved_at:] if moved_at is not None else []
        before = changes[moved_at - 1]["done"] if moved_at else None
        if moved_at is None:
            failures.append(
                f"never refining at {args.move_after} samples or more: no camera move made"
            )
        elif not any(c.get("state") == "moving" or (c.get("done") or 0) < before for c in after):
            failures.append("the camera move did not restart the refinement")
    await asyncio.sleep(1.0)  # the converged image painted
    if image_difference(point_jpeg, await newest_jpeg(devtools)) < 1.0:
        failures.append("the converged image is the point-light image")
    await devtools.evaluate(
        "document.querySelectorAll('.mantine-Notification-closeButton')"
        # viser's notice that WebGL runs in software
        ".forEach((b) => b.click())"
    )
    await asyncio.sleep(0.5)
    shot = await devtools.call("Page.captureScreenshot", format="png")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(base64.b64decode(shot["data"]))
    failures += [f"page exception: {e}" for e in devtools.exceptions[:3]]
    return changes, failures


def run(args: argparse.Namespace) -> int:
    job = Path(args.job)
    find_chromium(args.chromium)
    procs = Processes()
    try:
        load_before = os.getloadavg()
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
            "--samples",
            str(args.samples),
        ]
        process = procs.start(command, "viewer.log", env={**os.environ, "PYTHONUNBUFFERED": "1"})

        def found_url() -> str | None:
            match = re.search(
                r"olatbench view: .* at (http://127\.0\.0\.1:\d+)",
                (procs.temp / "viewer.log").read_text(),
            )
            return match.group(1) if match else None

        url = wait_for(
            found_url,
            args.startup_timeout,
            "olatbench view did not start",
            process,
            procs,
            "viewer.log",
        )
        page = start_chromium(procs, args)
        from websockets.asyncio.client import connect

        async def session() -> tuple[list[dict[str, Any]], list[str], str]:
            async with connect(page, max_size=None, open_timeout=30) as socket:
                devtools = DevTools(socket)
                try:
                    version = (await devtools.call("Browser.getVersion"))["product"]
                    print(
                        f"job {job}, viewer {url}, {version}, "
                        f"{'headed' if args.headed else 'headless'}, K = {args.samples}, map "
                        f"{args.map}",
                        flush=True,
                    )
                    changes, failures = await drive(devtools, url, args)
                    return changes, failures, version
                finally:
                    devtools.reader.cancel()

        changes, failures, version = asyncio.run(session())
        load_after = os.getloadavg()
    finally:
        procs.close()
    env = [c for c in changes if c.get("map") == args.map]
    converged = next((c for c in env if c["state"] == "converged"), None)
    print(
        f"screenshot {args.out}; load average {load_before[0]:.1f} before, {load_after[0]:.1f} "
        f"after, on {os.cpu_count()} CPUs; {version}"
    )
    for failure in failures:
        print(f"FAILED: {failure}")
    size = f"{converged['width']}x{converged['height']}" if converged else "none"
    print(
        f"SUMMARY viewer_envmap_browser samples={args.samples} map={args.map} "
        f"changes={len(changes)} converged_s={converged['t'] if converged else 'none'} "
        f"size={size} status={'ok' if not failures else 'failed'}"
    )
    return 1 if failures else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("job", help="a finished job folder")
    parser.add_argument(
        "--out", type=Path, required=True, help="the screenshot (PNG) of the converged view"
    )
    parser.add_argument(
        "--samples", type=int, default=64, help="K, passed to olatbench view (default 64)"
    )
    parser.add_argument(
        "--map", default="studio", help="the map to choose in the tab's menu (default studio)"
    )
    parser.add_argument(
        "--exposure", type=float, default=0.0, help="typed into the exposure box (stops)"
    )
    parser.add_argument(
        "--zoom-out",
        type=int,
        default=0,
        help="mouse-wheel steps (100 px each) on the canvas before the switch (default 0)",
    )
    parser.add_argument(
        "--move-after",
        type=int,
        default=12,
        help="drag the camera once this many samples are averaged (0: never; default 12)",
    )
    parser.add_argument(
        "--timeout", type=float, default=900.0, help="seconds for the view to converge"
    )
    parser.add_argument(
        "--startup-timeout",
        type=float,
        default=300.0,
        help="seconds for the viewer to restore the job and show its first image (default 300)",
    )
    parser.add_argument(
        "--window",
        type=int,
        nargs=2,
        default=(1100, 640),
        metavar=("W", "H"),
        help="browser window size (default 1100 640)",
    )
    parser.add_argument("--chromium", help="the browser executable (default: chromium on PATH)")
    parser.add_argument(
        "--headed", action="store_true", help="a visible window instead of headless"
    )
    parser.add_argument("--chromium-args", default="", help="extra chromium flags, one string")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        sys.exit(run(args))
    except BenchError as error:
        sys.exit(f"viewer_envmap_browser: {error}")
    except KeyboardInterrupt:
        print("viewer_envmap_browser: interrupted", file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    main()
