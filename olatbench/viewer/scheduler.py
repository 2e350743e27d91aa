"""The viewer's render scheduler: one render in flight, the newest request per view, progressive
resolution.

Browser events (camera orbits, light drags, slider moves) arrive far faster than a CPU renders.
`RenderScheduler` keeps, per key (one per browser tab and output), only the newest request: a
request replaced before it was rendered is dropped (`dropped` counts them). One worker thread
renders, so the UI callbacks that call `submit` never block and the model is never rendered by two
threads at once.

Progressive rendering: while requests for a key keep arriving (the last less than ``settle_seconds``
ago: the user is dragging) the worker renders it at the reduced ``preview`` quality; once the key
has been still for ``settle_seconds`` it renders the newest request once more at ``full`` quality.
Requests submitted with ``progressive=False`` (a snap to a dataset frame, a button) are rendered at
full quality at once.

Refinement: a request submitted with ``passes`` > 1 (the viewer's environment-map mode, which adds
light samples batch by batch) is rendered at full quality that many times in a row while it stays
the newest, each pass delivered (the request carries its own progress). A newer request of the key
supersedes it: no further pass of the old one starts, and the pass in flight can stop early:
``render`` may ask `superseded` while it works and raise `Superseded`, which drops the pass silently
(`cancelled` counts them).

Keys are served round-robin, so several tabs share the one worker fairly.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any, Literal

Quality = Literal["preview", "full"]


@dataclass
class _Slot:
    """What is known of one key: its newest request and how far it has been rendered."""

    request: Any
    generation: int  # increases with every submit
    submitted: float  # monotonic seconds of the newest submit
    progressive: bool
    passes: int = 1  # full-quality passes wanted
    rendered_generation: int = 0  # generation of the newest delivered render (0: none)
    rendered_quality: Quality | None = None
    rendered_passes: int = 0  # full-quality passes of rendered_generation started


class Superseded(Exception):
    """Raised by a render that stopped because its request was superseded
    (`RenderScheduler.superseded`)."""


class RenderScheduler:
    """Render the newest request of each key on one worker thread and hand each image to
    ``deliver``.

    ``render(request, quality) -> image`` runs on the worker; ``deliver(key, request, image,
    quality)`` runs on the worker right after. An exception in either is passed to
    ``on_error(key, error)`` (default: re-raised in the worker, which then stops) and the key is
    considered rendered (no further pass), except `Superseded`, which is dropped. Use as a context
    manager, or `start` / `close`.
    """

    def __init__(
        self,
        render: Callable[[Any, Quality], Any],
        deliver: Callable[[Hashable, Any, Any, Quality], None],
        *,
        settle_seconds: float = 0.25,
        on_error: Callable[[Hashable, BaseException], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.render = render
        self.deliver = deliver
        self.settle_seconds = settle_seconds
        self.on_error = on_error
        self.clock = clock
        self.dropped = 0  # requests replaced before any render of them started
        self.cancelled = 0  # passes that stopped early, superseded (`Superseded`)
        self.rendered = {"preview": 0, "full": 0}
        self._slots: dict[Hashable, _Slot] = {}
        self._order: list[Hashable] = []  # round-robin order of keys
        self._condition = threading.Condition()
        self._closed = False
        self._busy = False
        self._current: tuple[Hashable, int] | None = None  # (key, generation) being rendered
        self._thread = threading.Thread(
            target=self._run, name="olatbench-viewer-render", daemon=True
        )

    # -----------------------------------------------------------------------------------------
    # public
    def start(self) -> RenderScheduler:
        self._thread.start()
        return self

    def close(self, timeout: float | None = 10.0) -> None:
        """Stop the worker after the render in flight (pending requests are dropped)."""
        with self._condition:
            self._closed = True
            self._condition.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def __enter__(self) -> RenderScheduler:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def submit(
        self, key: Hashable, request: Any, progressive: bool = True, passes: int = 1
    ) -> None:
        """Make ``request`` the newest of ``key``, to be rendered ``passes`` times at full quality
        once still (never blocks on a render)."""
        if passes < 1:
            raise ValueError(f"passes must be at least 1, not {passes}")
        with self._condition:
            slot = self._slots.get(key)
            if slot is None:
                self._slots[key] = _Slot(request, 1, self.clock(), progressive, passes)
                self._order.append(key)
            else:
                if slot.rendered_generation < slot.generation:
                    self.dropped += 1  # the previous request was never started
                slot.request, slot.generation = request, slot.generation + 1
                slot.submitted, slot.progressive, slot.passes = self.clock(), progressive, passes
            self._condition.notify_all()

    def superseded(self) -> bool:
        """Asked by ``render`` on the worker: whether the request it renders is no longer its key's
        newest (or the scheduler is closing, or the key forgotten)."""
        with self._condition:
            if self._closed or self._current is None:
                return True
            key, generation = self._current
            slot = self._slots.get(key)
            return slot is None or slot.generation != generation

    def forget(self, key: Hashable) -> None:
        """Drop ``key`` and its pending request (a closed tab)."""
        with self._condition:
            if self._slots.pop(key, None) is not None:
                self._order.remove(key)

    def idle(self) -> bool:
        """Whether nothing is rendering and every key's newest request has been rendered at full
        quality."""
        with self._condition:
            return not self._busy and all(
                s.rendered_generation == s.generation
                and s.rendered_quality == "full"
                and s.rendered_passes >= s.passes
                for s in self._slots.values()
            )

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until `idle` (tests, recording); False on timeout."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.idle():
                return True
            time.sleep(0.005)
        return self.idle()

    # -----------------------------------------------------------------------------------------
    # worker
    def _next(self, now: float) -> tuple[Hashable, Any, int, Quality] | float | None:
        """The next job (key, request, generation, quality), else the seconds until one may become
        due (None: nothing pending at all)."""
        wait: float | None = None
        for offset in range(len(self._order)):
            key = self._order[offset]
            slot = self._slots[key]
            fresh = slot.rendered_generation < slot.generation
            still = now - slot.submitted >= self.settle_seconds or not slot.progressive
            refining = (
                not fresh and slot.rendered_quality == "full" and slot.rendered_passes < slot.passes
            )
            if fresh and not still:
                job: tuple[Hashable, Any, int, Quality] = (
                    key,
                    slot.request,
                    slot.generation,
                    "preview",
                )
            elif ((fresh or slot.rendered_quality != "full") and still) or refining:
                job = (key, slot.request, slot.generation, "full")
            else:
                # a preview shown; full once still
                if not fresh and slot.rendered_quality != "full":
                    remaining = self.settle_seconds - (now - slot.submitted)
                    wait = remaining if wait is None else min(wait, remaining)
                continue
            self._order.append(self._order.pop(offset))  # round robin: served keys go to the back
            return job
        return wait

    def _run(self) -> None:
        while True:
            with self._condition:
                while True:
                    if self._closed:
                        return
                    found = self._next(self.clock())
                    if isinstance(found, tuple):
                        break
                    self._condition.wait(timeout=None if found is None else max(found, 0.001))
                key, request, generation, quality = found
                self._busy = True
                slot = self._slots[key]
                same = slot.rendered_generation == generation and slot.rendered_quality == "full"
                slot.rendered_passes = (
                    0 if quality == "preview" else slot.rendered_passes + 1 if same else 1
                )
                # started = not dropped
                slot.rendered_generation, slot.rendered_quality = generation, quality
                self._current = (key, generation)
            try:
                image = self.render(request, quality)
                self.deliver(key, request, image, quality)
                self.rendered[quality] += 1
            except Superseded:
                self.cancelled += 1
            except Exception as error:  # handed to on_error, or re-raised
                with self._condition:
                    if slot.generation == generation:
                        # no further pass of a request that failed
                        slot.rendered_passes = slot.passes
                if self.on_error is None:
                    raise
                self.on_error(key, error)
            finally:
                with self._condition:
                    self._busy = False
                    self._current = None
                    self._condition.notify_all()
