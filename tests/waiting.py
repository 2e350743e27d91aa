"""Waiting in tests: on an event (a file appearing, a line printed, a process ending), never for a
fixed time.

`BACKSTOP_SECONDS` bounds every wait only so that a hung test ends: it is not a speed requirement,
and a busy machine (other test runs, builds, several agents on two cores) must stay far below it.
"""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Callable
from typing import TypeVar

BACKSTOP_SECONDS = 900.0

T = TypeVar("T")


def wait_until(
    condition: Callable[[], T],
    what: str,
    *,
    process: subprocess.Popen | None = None,
    timeout: float = BACKSTOP_SECONDS,
    poll: float = 0.02,
) -> T:
    """Poll ``condition`` until it returns something truthy and return that; fails (naming ``what``)
    when the backstop passes or ``process`` ends first."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if process is not None and process.poll() is not None:
            raise AssertionError(
                f"the process ended (exit code {process.returncode}) before {what}"
            )
        if time.monotonic() > deadline:
            raise AssertionError(f"no {what} within the {timeout:.0f} s backstop")
        time.sleep(poll)


def process_gone(pid: int) -> bool:
    """Whether no process ``pid`` exists any more (a zombie child of this process still counts as
    existing)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False
