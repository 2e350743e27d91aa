"""Run one command of an official implementation with its output streamed into the job's log.

The command runs in its own process group (session), so a timeout or an interruption ends it with
everything it started (``conda run``'s and a container runtime's children too): SIGTERM, then
SIGKILL after `KILL_GRACE` s.
"""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

LOG_TAIL_LINES = 25
KILL_GRACE = 10.0


class OfficialRunError(RuntimeError):
    """An official command failed: non-zero exit, could not start, timed out, or left renders
    out."""


@dataclass
class CommandRecord:
    """What ran: the step, its argument list, working folder, exit code (None: did not finish) and
    wall time (s); ``resumed``: an earlier attempt of the job finished it (its exit code and time),
    so it was not run again."""

    step: str
    argv: list[str]
    cwd: str
    exit_code: int | None = None
    seconds: float | None = None
    resumed: bool = False

    def to_json(self) -> dict:
        return {
            "step": self.step,
            "argv": self.argv,
            "command": shlex.join(self.argv),
            "cwd": self.cwd,
            "exit_code": self.exit_code,
            "seconds": None if self.seconds is None else round(self.seconds, 3),
            "resumed": self.resumed,
        }


def log_tail(path: Path, start: int = 0, lines: int = LOG_TAIL_LINES) -> str:
    """The last ``lines`` lines of ``path`` after byte offset ``start`` ("" when there are none)."""
    if not path.is_file():
        return ""
    with open(path, "rb") as handle:
        handle.seek(start)
        text = handle.read().decode("utf-8", errors="replace")
    return "\n".join(text.splitlines()[-lines:])


def _end_group(process: subprocess.Popen) -> None:
    """Terminate the command's process group, then kill it if it outlives `KILL_GRACE`."""
    for sig, wait in ((signal.SIGTERM, KILL_GRACE), (signal.SIGKILL, None)):
        try:
            os.killpg(process.pid, sig)
        except (ProcessLookupError, PermissionError):
            return
        try:
            process.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def run_command(
    record: CommandRecord,
    log_path: Path,
    env: Mapping[str, str] | None = None,
    timeout: float | None = None,
) -> None:
    """Run ``record.argv`` in ``record.cwd``, appending stdout and stderr to ``log_path``; fills in
    the exit code and wall time. Raises `OfficialRunError` (exit code or timeout, the command line
    and the log's last lines); on any interruption (KeyboardInterrupt, SystemExit) the process group
    is ended before it propagates."""
    log_path.parent.mkdir(parents=True, exist_ok=True)
    line = shlex.join(record.argv)
    with open(log_path, "ab") as log:
        log.write(f"$ (cd {shlex.quote(record.cwd)} && {line})\n".encode())
        log.flush()
        start = log.tell()
        clock = time.perf_counter()
        try:
            process = subprocess.Popen(
                record.argv,
                cwd=record.cwd,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                env={**os.environ, **(env or {})},
                start_new_session=True,
            )
        except OSError as error:
            raise OfficialRunError(
                f"{record.step}: cannot start {record.argv[0]!r} ({error.strerror}); "
                f"command: {line}"
            ) from None
        try:
            record.exit_code = process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            _end_group(process)
            record.seconds = time.perf_counter() - clock
            raise OfficialRunError(
                f"{record.step} timed out after {timeout / 60:g} min and was stopped\n"
                f"command: {line}\nlast lines of {log_path}:\n{log_tail(log_path, start)}"
            ) from None
        except BaseException:
            _end_group(process)
            raise
        finally:
            record.seconds = time.perf_counter() - clock
    if record.exit_code != 0:
        raise OfficialRunError(
            f"{record.step} failed with exit code {record.exit_code}\ncommand: {line}\n"
            f"last lines of {log_path}:\n{log_tail(log_path, start)}"
        )
