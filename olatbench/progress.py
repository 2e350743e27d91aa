"""The one progress bar every verb uses: tqdm on a terminal, plain lines everywhere else.

On a terminal `progress_bar` is tqdm (``tqdm.auto``), redrawn in place with ``\\r`` and, for nested
bars (``position`` > 0), cursor-movement codes. Written into a file, a pipe, a Slurm log or a CI log
those codes turn into clutter, so when the stream is not a terminal `progress_bar` returns a
`PlainProgress` instead: it writes whole lines only (``desc: 30/100 step (30%) 0:12 elapsed,
loss=0.12``): one at the start and a summary at the end; in between, for work long enough to need
it, a line when another tenth is done and ``interval`` seconds have passed since the last line (so
at most one per 10 %; a bar without a total: one every ``interval`` seconds). A verb that takes
seconds (validating 36 frames) writes two lines. `progress_write` prints a message between the bars
in either mode.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterable, Iterator, Mapping
from typing import IO, Any

# between the first and last plain lines, at least this long between two lines
PLAIN_INTERVAL_SECONDS = 60.0


def _is_terminal(stream: IO[str] | None) -> bool:
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except ValueError:  # a closed stream
        return False


def _clock(seconds: float) -> str:
    minutes, secs = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class PlainProgress:
    """A progress bar as plain lines (no ``\\r``, no cursor codes): the part of tqdm's interface the
    project uses (iteration, ``update``, ``set_postfix``, ``set_postfix_str``, ``close``, context
    manager).

    Accepts and ignores tqdm's layout arguments (``position``, ``leave``, ``unit_scale``, …)."""

    def __init__(
        self,
        iterable: Iterable[Any] | None = None,
        *,
        total: float | None = None,
        desc: str | None = None,
        unit: str = "it",
        initial: float = 0,
        disable: bool = False,
        file: IO[str] | None = None,
        interval: float = PLAIN_INTERVAL_SECONDS,
        **ignored: Any,
    ) -> None:
        self.iterable = iterable
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)  # type: ignore[arg-type]
        self.total, self.desc, self.unit, self.n = total, desc, unit, initial
        self.disable, self.interval = disable, interval
        self.file = file
        self.postfix = ""
        self.started = time.monotonic()
        self._last_line = -float("inf")
        self._last_tenth = -1
        self._written_n: float | None = None
        self._closed = False
        self._lock = threading.Lock()  # downloads update one bar from several threads
        if not disable:
            self._write_line()

    # ----------------------------------------------------------------------------------------
    # tqdm's interface
    def __iter__(self) -> Iterator[Any]:
        if self.iterable is None:
            raise TypeError("this progress bar has no iterable")
        try:
            for item in self.iterable:
                yield item
                self.update(1)
        finally:
            self.close()

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def update(self, n: float = 1) -> None:
        with self._lock:
            self.n += n
            if self.disable:
                return
            if time.monotonic() - self._last_line < self.interval:
                return
            if not self.total or int(10 * self.n / self.total) > self._last_tenth:
                self._write_line()

    def set_postfix(
        self, values: Mapping[str, Any] | None = None, refresh: bool = True, **kwargs: Any
    ) -> None:
        items = {**(values or {}), **kwargs}
        self.postfix = ", ".join(f"{key}={value}" for key, value in items.items())

    def set_postfix_str(self, text: str = "", refresh: bool = True) -> None:
        self.postfix = str(text)

    def refresh(self) -> None:
        if not self.disable:
            self._write_line()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if not self.disable and self.n != self._written_n:  # the last state, unless already written
            self._write_line()

    # ----------------------------------------------------------------------------------------------
    # lines
    def line(self) -> str:
        """The text of the current state, e.g. ``train: 30/100 step (30%) 0:12 elapsed,
        loss=0.12``."""
        count = f"{self.n:g}/{self.total:g}" if self.total else f"{self.n:g}"
        share = f" ({100 * self.n / self.total:.0f}%)" if self.total else ""
        text = (
            f"{self.desc + ': ' if self.desc else ''}{count} {self.unit}{share} "
            f"{_clock(time.monotonic() - self.started)} elapsed"
        )
        return text + (f", {self.postfix}" if self.postfix else "")

    def _write_line(self) -> None:
        stream = self.file if self.file is not None else sys.stderr
        stream.write(self.line() + "\n")
        stream.flush()
        self._last_line = time.monotonic()
        self._last_tenth = int(10 * self.n / self.total) if self.total else -1
        self._written_n = self.n


def progress_bar(
    iterable: Iterable[Any] | None = None, *, file: IO[str] | None = None, **kwargs: Any
) -> Any:
    """A progress bar over ``iterable`` (or updated by hand): tqdm's arguments (``total``, ``desc``,
    ``unit``, ``position``, ``leave``, ``disable``, …). tqdm when ``file`` (default: standard error)
    is a terminal, else `PlainProgress`."""
    stream = file if file is not None else sys.stderr
    if _is_terminal(stream):
        from tqdm.auto import tqdm

        return tqdm(iterable, file=file, **kwargs)
    return PlainProgress(iterable, file=file, **kwargs)


def progress_write(text: str, file: IO[str] | None = None) -> None:
    """Print ``text`` as a line of its own between progress bars
    (tqdm's ``write`` on a terminal)."""
    stream = file if file is not None else sys.stderr
    if _is_terminal(stream):
        from tqdm.auto import tqdm

        tqdm.write(text, file=stream)
    else:
        stream.write(text + "\n")
        stream.flush()


__all__ = ["PlainProgress", "progress_bar", "progress_write"]
