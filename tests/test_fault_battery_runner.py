"""The runner's fault battery (#38, #48): each fault gives one clear error, the documented exit
code, no traceback, and loses nothing.

Faults: a read-only run folder (`status`, `run`, `report`, `evaluate`), a disk that fills up during
a run, a damaged results.json / job.json of a finished job, a newest checkpoint that does not load
(every way: unreadable, another format, job or config, a field missing, RNG states), a job run by
another process, a job another process finished (or another job took its folder) after the plan, a
``--jobs 2`` worker killed, and SIGTERM to ``olatbench run``.

Read-only folders and full disks are each tested up to three ways: a real tmpfs mounted in the
test's folder (root with CAP_SYS_ADMIN; remounted read-only, or filled up), file modes (read-only
cases; they bind a non-root user only), and `SimulatedFault` at the OS-error level (writes below the
run folder raise ``EROFS`` / ``ENOSPC``), which runs everywhere. A way the machine does not allow is
skipped with its reason, never passed silently. The number of faults is `FAULT_COUNT`, stated in
docs/guarantees.md.
"""

from __future__ import annotations

import builtins
import errno
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import test_runner_support as support
import torch
from click.testing import CliRunner
from waiting import BACKSTOP_SECONDS, process_gone, wait_until

from olatbench.bench.checkpoints import list_checkpoints
from olatbench.bench.execute import run_job
from olatbench.bench.plan import PlanOptions, make_plan
from olatbench.bench.results import read_results
from olatbench.bench.store import is_locked, job_lock, job_state
from olatbench.cli import main
from olatbench.datasets import suites

ROOT = Path(__file__).resolve().parents[1]


# ---- fixtures ------------------------------------------------------------------------------------


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


@pytest.fixture(autouse=True)
def tiny_suite(monkeypatch):
    """The tiny suite registered as 'tiny' for the CLI."""
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())


def run_cli(*args: str | Path):
    """``olatbench ARGS`` in this process; the result keeps stdout and stderr apart and together."""
    return CliRunner().invoke(main, [str(arg) for arg in args])


def run_args(data: Path, out: Path, *extra: str | Path) -> list[str | Path]:
    return [
        "run",
        "-m",
        "trivial",
        "-s",
        "tiny",
        "--data-root",
        data,
        "--out",
        out,
        "--quiet",
        "--device",
        "cpu",
        *extra,
    ]


def assert_one_clear_error(result, exit_code: int, *phrases: str) -> None:
    """The documented exit code, no traceback, exactly one ``Error:`` line holding every phrase."""
    assert result.exit_code == exit_code, result.output
    assert "Traceback" not in result.output, result.output
    assert not isinstance(result.exception, Exception) or isinstance(
        result.exception, SystemExit
    ), result.exception
    errors = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1, result.output
    for phrase in phrases:
        assert phrase in errors[0], errors[0]


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (relative path -> bytes): what "nothing lost" compares."""
    return {
        str(path.relative_to(folder)): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


def can_mount() -> bool:
    return os.geteuid() == 0 and shutil.which("mount") is not None


@contextmanager
def tmpfs(path: Path, size: str) -> Iterator[Path]:
    """A tmpfs of ``size`` mounted on ``path`` (skips the test when the machine does not allow
    it)."""
    path.mkdir(parents=True, exist_ok=True)
    if not can_mount():
        pytest.skip("mounting a tmpfs needs root; the simulated case covers this fault here")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
        capture_output=True,
        text=True,
    )
    if mounted.returncode != 0:
        pytest.skip(
            f"cannot mount a tmpfs here ({mounted.stderr.strip()}); the simulated case covers "
            "this fault"
        )
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def plan(data: Path, out: Path, **kwargs):
    return make_plan("trivial", support.tiny_suite(), out, data_root=data, progress=False, **kwargs)


def job_folder(out: Path, scene: str = "Alpha", seed: int = 0, variant: str = "default") -> Path:
    return out / "tiny" / "trivial" / variant / scene / f"seed{seed}"


# ---- read-only run folders (#38 item 4) ----------------------------------------------------------

READ_ONLY_MODES = ("tmpfs-ro", "file-modes", "simulated")


@contextmanager
def read_only(out: Path, mode: str, monkeypatch) -> Iterator[None]:
    """Make ``out`` (a tmpfs mount point for ``tmpfs-ro``) read-only for the duration."""
    if mode == "simulated":
        fault = SimulatedFault(monkeypatch, out, errno.EROFS)
        fault.on()
        try:
            yield
        finally:
            fault.off()
        return
    if mode == "tmpfs-ro":
        subprocess.run(["mount", "-o", "remount,ro", str(out)], check=True)
        try:
            yield
        finally:
            subprocess.run(["mount", "-o", "remount,rw", str(out)], check=True)
        return
    if os.geteuid() == 0:
        pytest.skip(
            "file modes do not bind root; the tmpfs-ro and simulated cases cover this fault"
        )
    paths = [out, *out.rglob("*")]
    modes = {path: path.stat().st_mode for path in paths}
    for path in paths:
        path.chmod(stat.S_IMODE(modes[path]) & ~0o222)
    try:
        yield
    finally:
        for path in reversed(paths):
            path.chmod(stat.S_IMODE(modes[path]))


@contextmanager
def output_folder(tmp_path: Path, mode: str) -> Iterator[Path]:
    if mode == "tmpfs-ro":
        with tmpfs(tmp_path / "runs", "16m") as out:
            yield out
    else:
        yield tmp_path / "runs"


READ_ONLY_CASES = {
    # name: (argv after the fixed part, exit code, phrases of the one error line or None, phrase of
    # the output)
    "status": (["status", "{out}"], 0, None, "1 done, 1 failed"),
    "status --json": (["status", "{out}", "--json"], 0, None, '"state": "failed"'),
    "run of done jobs": (["run", "--scenes", "Alpha"], 0, None, "1 already done, 0 to run"),
    "run of a new job": (
        ["run", "--scenes", "Beta"],
        1,
        ("cannot write", "Read-only file system|Permission denied", "--output"),
        None,
    ),
    "run retrying a failed job": (
        ["run", "--scenes", "Alpha", "--variant", "fails"],
        1,
        ("cannot write", "Read-only file system|Permission denied", "--output"),
        None,
    ),
    "report to stdout": (["report", "{out}"], 0, None, "Alpha"),
    "report -o into it": (
        ["report", "{out}", "-o", "{out}/table.md"],
        1,
        ("cannot write", "table.md", "Read-only file system|Permission denied"),
        None,
    ),
    "evaluate -o into it": (
        [
            "evaluate",
            "{tmp}/pred",
            "--gt",
            "{tmp}/data/Alpha",
            "--protocol",
            support.FAST_PROTOCOL,
            "-o",
            "{out}/scores.json",
        ],
        1,
        ("cannot write", "scores.json", "Read-only file system|Permission denied"),
        None,
    ),
}


@pytest.mark.parametrize("mode", READ_ONLY_MODES)
@pytest.mark.parametrize("case", list(READ_ONLY_CASES))
def test_a_read_only_run_folder(data, tmp_path, monkeypatch, case, mode):
    argv, code, error_phrases, phrase = READ_ONLY_CASES[case]
    with output_folder(tmp_path, mode) as out:
        assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
        assert (
            run_cli(*run_args(data, out, "--scenes", "Alpha", "--variant", "fails")).exit_code == 1
        )
        # predictions to score
        shutil.copytree(job_folder(out) / "renders" / "test", tmp_path / "pred")
        before = snapshot(out)
        with read_only(out, mode, monkeypatch):
            if argv[0] == "run":
                argv = run_args(data, out, *argv[1:])
            result = run_cli(
                *[
                    str(arg).replace("{out}", str(out)).replace("{tmp}", str(tmp_path))
                    for arg in argv
                ]
            )
            assert result.exit_code == code, result.output
            assert "Traceback" not in result.output
            if error_phrases:
                errors = [line for line in result.output.splitlines() if line.startswith("Error:")]
                assert len(errors) == 1, result.output
                for alternatives in error_phrases:
                    assert any(option in errors[0] for option in alternatives.split("|")), errors[0]
            else:
                assert phrase in result.output, result.output
        assert snapshot(out) == before  # nothing written, nothing lost


# ---- a disk that fills up during a run (#38 item 6) ----------------------------------------------

DISK_MODES = ("tmpfs", "simulated")


def _fill(folder: Path) -> None:
    """Write a filler file into ``folder`` until its file system is full."""
    with open(folder / "filler", "wb") as handle:
        try:
            while True:
                handle.write(b"\0" * 65536)
                handle.flush()
        except OSError as error:
            assert error.errno == errno.ENOSPC


class SimulatedFault:
    """Writes below ``folder`` fail with ``code`` (``ENOSPC``: a full disk, ``EROFS``: a read-only
    file system) once `on` is called, in this process: opening a file for writing, making a
    temporary file or a folder, renaming onto a name, and ``os.access(..., W_OK)``. The OS-level
    stand-in where the machine cannot mount a tmpfs."""

    def __init__(self, monkeypatch, folder: Path, code: int) -> None:
        self.active, self.folder, self.code = False, str(folder), code
        real_open, real_mkstemp, real_replace = builtins.open, tempfile.mkstemp, os.replace
        real_mkdir, real_access = os.mkdir, os.access

        def refused(path) -> bool:
            return self.active and os.path.abspath(os.fspath(path)).startswith(self.folder)

        def error(path) -> OSError:
            return OSError(self.code, os.strerror(self.code), os.fspath(path))

        def open_(file, mode="r", *args, **kwargs):
            if (
                isinstance(file, (str, os.PathLike))
                and any(flag in mode for flag in "wax+")
                and refused(file)
            ):
                raise error(file)
            return real_open(file, mode, *args, **kwargs)

        def mkstemp(*args, dir=None, **kwargs):
            if dir is not None and refused(dir):
                raise error(dir)
            return real_mkstemp(*args, dir=dir, **kwargs)

        def replace(source, target, *args, **kwargs):
            if refused(target):
                raise error(target)
            return real_replace(source, target, *args, **kwargs)

        def mkdir(path, *args, **kwargs):
            if refused(path):
                raise error(path)
            return real_mkdir(path, *args, **kwargs)

        def access(path, mode, *args, **kwargs):
            if mode & os.W_OK and refused(path):
                return False
            return real_access(path, mode, *args, **kwargs)

        for owner, name, function in (
            (builtins, "open", open_),
            (tempfile, "mkstemp", mkstemp),
            (os, "replace", replace),
            (os, "mkdir", mkdir),
            (os, "access", access),
        ):
            monkeypatch.setattr(owner, name, function)

    def on(self) -> None:
        self.active = True

    def off(self) -> None:
        self.active = False


class _SimulatedFullDisk:
    def __init__(self, monkeypatch, folder: Path) -> None:
        self.fault = SimulatedFault(monkeypatch, folder, errno.ENOSPC)

    def fill(self, folder: Path) -> None:
        self.fault.on()

    def free(self, folder: Path) -> None:
        self.fault.off()


class _RealFullDisk:
    def fill(self, folder: Path) -> None:
        _fill(folder)

    def free(self, folder: Path) -> None:
        (folder / "filler").unlink()


@pytest.mark.parametrize("mode", DISK_MODES)
def test_a_full_disk_fails_each_job_cleanly_and_the_rerun_finishes_them(
    data, tmp_path, monkeypatch, mode
):
    """The disk fills up at the first checkpoint of the first job to run: that job fails although
    neither its checkpoint nor its error.txt can be written, and every later job still starts and
    fails with one line; the job finished before keeps its files; once space is freed, the same
    command finishes every job."""
    import olatbench.bench.execute as execute

    with (
        tmpfs(tmp_path / "runs", "8m") if mode == "tmpfs" else _nullcontext(tmp_path / "runs")
    ) as out:
        assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
        finished = snapshot(job_folder(out))
        disk = _RealFullDisk() if mode == "tmpfs" else _SimulatedFullDisk(monkeypatch, out)
        real_save = execute.save_checkpoint

        def save_on_a_filling_disk(*args, **kwargs):
            disk.fill(out)
            return real_save(*args, **kwargs)

        monkeypatch.setattr(execute, "save_checkpoint", save_on_a_filling_disk)
        result = run_cli(*run_args(data, out, "--seeds", "2"))
        monkeypatch.setattr(execute, "save_checkpoint", real_save)
        assert result.exit_code == 1, result.output
        assert "Traceback" not in result.output
        assert "3 job(s) failed" in result.output
        failed = [line for line in result.output.splitlines() if line.startswith("FAILED ")]
        assert len(failed) == 3 and all("No space left on device" in line for line in failed), (
            result.output
        )
        # the second failure: error.txt could not be written
        assert "not recorded in the folder" in failed[0]
        disk.free(out)
        assert snapshot(job_folder(out)) == finished
        rerun = run_cli(*run_args(data, out, "--seeds", "2"))
        assert rerun.exit_code == 0, rerun.output
        for scene in ("Alpha", "Beta"):
            for seed in (0, 1):
                assert job_state(job_folder(out, scene, seed)).state == "done"


@contextmanager
def _nullcontext(value):
    yield value


# ---- damaged records of a finished job (#38 items 5 and 12) --------------------------------------


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


RESULTS_DAMAGE = {
    "truncated": _truncate,
    "zero bytes": lambda path: path.write_bytes(b""),
    "missing": lambda path: path.unlink(),
    "not UTF-8": lambda path: path.write_bytes(b"\xff\xfe{\x00"),
    "another job's": lambda path: path.write_text(path.read_text().replace('"id": "', '"id": "0')),
}
JOB_FILE_DAMAGE = {
    "truncated": _truncate,
    "zero bytes": lambda path: path.write_bytes(b""),
    "not an object": lambda path: path.write_text("[]"),
    "not UTF-8": lambda path: path.write_bytes(b"\xff\xfe{\x00"),
}


@pytest.mark.parametrize("damage", list(RESULTS_DAMAGE))
def test_a_finished_job_with_a_damaged_results_json_is_reported_and_re_evaluated(
    data, tmp_path, damage
):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out)).exit_code == 0
    folder = job_folder(out)
    original = read_results(folder / "results.json")
    checkpoint = list_checkpoints(folder)[-1][1].read_bytes()
    RESULTS_DAMAGE[damage](folder / "results.json")
    damaged = (folder / "results.json").read_bytes() if (folder / "results.json").exists() else None

    state = job_state(folder)
    assert (
        state.state == "damaged"
        and "results.json" in state.message
        and "olatbench run" in state.message
    )
    status = run_cli("status", out)
    assert status.exit_code == 0 and "damaged" in status.output and "Traceback" not in status.output
    # a missing file is no result; another job's is readable
    if damage not in ("missing", "another job's"):
        report = run_cli("report", out)
        assert report.exit_code == 0 and "Traceback" not in report.output, report.output
        assert (
            "skipped (unreadable)" in report.stderr
            and str(folder / "results.json") in report.stderr
        )
        assert "Beta" in report.stdout  # the other job's results still make the table

    rerun = run_cli(*run_args(data, out))
    assert rerun.exit_code == 0 and "1 damaged: re-evaluated" in rerun.output, rerun.output
    # what was there is kept under a name that says so, and the run said where (#58)
    if damaged is not None:
        assert (folder / "results.json.damaged").read_bytes() == damaged
        assert f"kept as {folder / 'results.json.damaged'}" in rerun.output, rerun.output
        assert f"kept as {folder / 'results.json.damaged'}" in (folder / "log.txt").read_text()
    repaired = read_results(folder / "results.json")
    # the final checkpoint, evaluated again: nothing lost
    assert repaired["metrics"] == original["metrics"]
    assert list_checkpoints(folder)[-1][1].read_bytes() == checkpoint
    assert "training already complete" in (folder / "log.txt").read_text()
    assert job_state(folder).state == "done"


@pytest.mark.parametrize("damage", list(JOB_FILE_DAMAGE))
def test_a_finished_job_with_a_damaged_job_json_is_not_partial_and_is_re_evaluated(
    data, tmp_path, damage
):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    folder = job_folder(out)
    job_json, original = (folder / "job.json").read_text(), read_results(folder / "results.json")
    JOB_FILE_DAMAGE[damage](folder / "job.json")
    damaged = (folder / "job.json").read_bytes()

    state = job_state(folder)
    assert (
        state.state == "damaged"
        and "job.json" in state.message
        and "olatbench run" in state.message
    )
    status = run_cli("status", out)
    assert status.exit_code == 0 and "damaged" in status.output and "None" not in status.output, (
        status.output
    )
    assert "partial" not in status.output

    rerun = run_cli(*run_args(data, out, "--scenes", "Alpha"))
    assert rerun.exit_code == 0 and "1 damaged: re-evaluated" in rerun.output, rerun.output
    # kept (#58)
    assert (
        folder / "job.json.damaged"
    ).read_bytes() == damaged and "job.json.damaged" in rerun.output
    assert (folder / "job.json").read_text() == job_json
    assert read_results(folder / "results.json")["metrics"] == original["metrics"]


def test_report_lists_each_unreadable_results_json_and_fails_only_when_none_is_readable(
    data, tmp_path
):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    (job_folder(out) / "results.json").write_text("{")
    result = run_cli("report", out)
    assert_one_clear_error(result, 1, "no readable results.json", "1 unreadable")
    assert "skipped (unreadable)" in result.output and "malformed JSON" in result.output


# ---- an unreadable newest checkpoint (#38 item 11) -----------------------------------------------


def _edit_payload(edit):
    """A damage that loads the checkpoint, applies ``edit(payload)`` and saves it back
    (a well-formed file)."""

    def damage(path: Path) -> None:
        payload = torch.load(path, weights_only=True)
        edit(payload)
        torch.save(payload, path)

    return damage


# name: (damage, phrase of the message, every checkpoint damaged or only the newest)
CHECKPOINT_DAMAGE = {
    "truncated": (_truncate, "cannot read checkpoint", False),
    "zero bytes": (lambda path: path.write_bytes(b""), "cannot read checkpoint", False),
    "not a checkpoint": (
        lambda path: path.write_bytes(os.urandom(4096)),
        "cannot read checkpoint",
        False,
    ),
    # all of them truncated: the job starts over
    "every checkpoint": (_truncate, "cannot read checkpoint", True),
    "not a zip": (lambda path: path.write_text('{"step": 8}'), "cannot read checkpoint", False),
    "an object weights_only refuses": (
        _edit_payload(lambda payload: payload.update(note=Path("x"))),
        "cannot read checkpoint",
        False,
    ),
    "another format tag": (
        _edit_payload(lambda payload: payload.update(format=99)),
        "checkpoint format 99",
        False,
    ),
    "another job's": (
        _edit_payload(lambda payload: payload.update(job_id="0" * 16)),
        "checkpoint of job 0000",
        False,
    ),
    "a field missing": (
        _edit_payload(lambda payload: payload.pop("rng")),
        "field 'rng' is not a dict",
        False,
    ),
    "another config's state": (
        _edit_payload(lambda payload: payload["method"].update(gain=torch.ones(2))),
        "does not load into trivial (RuntimeError",
        False,
    ),
    "every checkpoint another config's": (
        _edit_payload(lambda payload: payload["method"].update(gain=torch.ones(2))),
        "does not load into trivial (RuntimeError",
        True,
    ),
    "damaged RNG states": (
        _edit_payload(lambda payload: payload["rng"].update(torch=torch.zeros(3).byte())),
        "does not load into trivial",
        False,
    ),
}


@pytest.mark.parametrize("damage", list(CHECKPOINT_DAMAGE))
def test_an_unreadable_newest_checkpoint_resumes_from_the_newest_that_loads(data, tmp_path, damage):
    """Whatever keeps a checkpoint from loading into its job's method, it is set aside as
    ``.unreadable``, named with the reason on stderr and in log.txt, and the next older one is used
    (step 0 when none loads, from the same set-up as an uninterrupted run even after a state
    half-loaded into the method): the result is bit-exact."""
    harm, phrase, every = CHECKPOINT_DAMAGE[damage]
    options = PlanOptions(checkpoint_every=4)
    job = plan(data, tmp_path / "runs", scenes=["Alpha"], iterations=10, options=options)[0]
    reference = plan(
        data, tmp_path / "reference", scenes=["Alpha"], iterations=10, options=options
    )[0]
    # same id
    interrupted = type(job)(**{**job.__dict__, "config": {**job.config, "interrupt_at_step": 9}})
    with pytest.raises(KeyboardInterrupt):
        run_job(interrupted, progress=False)
    folder = Path(job.folder)
    assert [step for step, _ in list_checkpoints(folder)] == [4, 8]
    damaged = list_checkpoints(folder) if every else list_checkpoints(folder)[-1:]
    for _, path in damaged:
        harm(path)
    kept = {path.name + ".unreadable": path.read_bytes() for _, path in damaged}

    result = run_cli(
        *run_args(
            data,
            tmp_path / "runs",
            "--scenes",
            "Alpha",
            "--iterations",
            "10",
            "--checkpoint-every",
            "4",
        )
    )
    assert result.exit_code == 0 and "Traceback" not in result.output, result.output
    assert phrase in result.stderr and "step_00000008.pt.unreadable" in result.stderr, result.stderr
    assert str(damaged[-1][1]) in result.stderr  # the file is named
    log = (folder / "log.txt").read_text()
    assert phrase in log and ("resumed from step_00000004.pt" in log) == (not every)
    for name, content in kept.items():  # the damaged files are kept aside, not deleted
        assert (folder / "checkpoints" / name).read_bytes() == content

    assert run_job(reference, progress=False).status == "done"
    resumed, uninterrupted = (
        read_results(Path(j.folder) / "results.json") for j in (job, reference)
    )
    assert resumed["metrics"] == uninterrupted["metrics"]  # exact: the resume is bit-exact
    weights = [
        torch.load(list_checkpoints(j.folder)[-1][1], weights_only=True)["method"]["logits"]
        for j in (job, reference)
    ]
    assert torch.equal(*weights)


# the 3DGS method's own check refuses the state: the "not a 3DGS checkpoint"
GAUSSIAN_STATE_DAMAGE = {
    "another model's format tag": (
        lambda state: state.update(format="olatbench.ssdgs/1"),
        "not a 3DGS checkpoint",
    ),
    "another config's": (
        lambda state: state["config"].update(sh_degree=0),
        "written with a different config",
    ),
}


@pytest.mark.parametrize("damage", list(GAUSSIAN_STATE_DAMAGE))
def test_a_gaussian_checkpoint_its_method_refuses_is_set_aside_and_named(
    tmp_path, monkeypatch, damage
):
    """#48 item 3 with a real Gaussian method: a newest checkpoint that 3DGS refuses (``ValueError:
    not a 3DGS checkpoint``, naming no file, stopped every rerun) is set aside, named, and the job
    resumes from the one before."""
    import dataclasses

    from olatbench.bench.plan import load_method_class

    edit, phrase = GAUSSIAN_STATE_DAMAGE[damage]
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    job = make_plan(
        "3dgs",
        support.tiny_suite(scenes=("Alpha",)),
        tmp_path / "runs",
        variants=["mini"],
        iterations=12,
        data_root=data,
        progress=False,
        options=PlanOptions(checkpoint_every=4),
    )[0]
    job = dataclasses.replace(job, config={**job.config, "num_init_gaussians": 300}).with_id()
    method_class = load_method_class(job)
    train_step = method_class.train_step

    def interrupted_at_10(self, step):
        if step == 10:
            raise KeyboardInterrupt
        return train_step(self, step)

    monkeypatch.setattr(method_class, "train_step", interrupted_at_10)
    with pytest.raises(KeyboardInterrupt):
        run_job(job, progress=False)
    monkeypatch.setattr(method_class, "train_step", train_step)
    folder = Path(job.folder)
    assert [step for step, _ in list_checkpoints(folder)] == [4, 8]
    newest = list_checkpoints(folder)[-1][1]
    _edit_payload(lambda payload: edit(payload["method"]))(newest)

    outcome = run_job(job, progress=False)
    assert outcome.status == "done", outcome.error
    log = (folder / "log.txt").read_text()
    assert phrase in log and str(newest) in log and "resumed from step_00000004.pt" in log, log
    assert (folder / "checkpoints" / "step_00000008.pt.unreadable").is_file()


# ---- a job run by another process (#38 item 12) --------------------------------------------------


def test_a_run_that_leaves_a_job_to_another_process_exits_3_and_the_rerun_0(data, tmp_path):
    out = tmp_path / "runs"
    help_text = run_cli("run", "--help").output
    assert "3 when none failed but some" in " ".join(help_text.split())
    # another process (here: another open file) runs Alpha
    with job_lock(job_folder(out)) as acquired:
        assert acquired
        from olatbench.bench.session import write_pending

        write_pending(plan(data, out, scenes=["Alpha"]))  # as that process has
        result = run_cli(*run_args(data, out))
        assert result.exit_code == 3, result.output
        assert "Traceback" not in result.output and "1 running in another process" in result.output
        assert "rerun the same command once they finish" in result.output
        status = run_cli("status", out)
        assert status.exit_code == 0 and "running" in status.output
        assert not (job_folder(out) / "results.json").exists()  # untouched
        assert job_state(job_folder(out, "Beta")).state == "done"
    rerun = run_cli(*run_args(data, out))
    assert rerun.exit_code == 0, rerun.output
    assert job_state(job_folder(out)).state == "done"
    # a job that another process locked between the plan and its turn comes back "skipped": the same
    # exit code
    from olatbench.bench.execute import JobOutcome
    from olatbench.bench.session import RunSummary

    locked = JobOutcome(
        "id", "Alpha/default/seed0", str(out), "skipped", error="running in another process"
    )
    assert RunSummary([locked], running=0).exit_code == 3


# ---- a job another process finished after this one planned it (#48 item 1) -----------------------


def _as_planned_before(monkeypatch, folder: Path, state: str = "pending") -> None:
    """The CLI sees ``folder`` in ``state``, as a process that planned it before another one
    finished it did."""
    import olatbench.bench.store as store

    real = store.job_state

    def planned_view(path, expected_id=None):
        found = real(path, expected_id)
        return store.JobState(found.folder, state, found.job_id) if Path(path) == folder else found

    monkeypatch.setattr(store, "job_state", planned_view)


def _run_cli_with_the_plan_outdated(data, out, monkeypatch, folder):
    _as_planned_before(monkeypatch, folder)
    return run_cli(*run_args(data, out))


def _run_job_of_the_outdated_plan(data, out, monkeypatch, folder):
    return run_job(plan(data, out, scenes=["Alpha"])[0], progress=False)


def _run_local_of_the_outdated_plan(data, out, monkeypatch, folder):
    from olatbench.bench.executors import run_local

    return run_local(plan(data, out, scenes=["Alpha"]), workers=2, progress=False)[0]


FINISHED_ELSEWHERE = {  # how the process that planned the job before it finished gets to it
    "olatbench run (planned as pending)": _run_cli_with_the_plan_outdated,
    "run_job of the outdated plan": _run_job_of_the_outdated_plan,
    "--jobs 2 worker of the outdated plan": _run_local_of_the_outdated_plan,
}


@pytest.mark.parametrize("way", list(FINISHED_ELSEWHERE))
def test_a_job_finished_after_the_plan_is_never_redone(data, tmp_path, monkeypatch, way):
    """Process B planned the job while it was pending; process A finished it; B then takes the free
    lock. B reads the job's state again under the lock and leaves it: its DONE, results.json,
    checkpoint and log are untouched."""
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0  # process A
    folder = job_folder(out)
    finished = snapshot(folder)
    outcome = FINISHED_ELSEWHERE[way](data, out, monkeypatch, folder)
    if way.startswith("olatbench run"):
        assert outcome.exit_code == 0 and "Traceback" not in outcome.output, outcome.output
        assert job_state(job_folder(out, "Beta")).state == "done"  # the other job of B's plan ran
    else:
        assert outcome.status == "done", outcome
        assert (
            outcome.test_metrics == read_results(folder / "results.json")["metrics"]["test"]["mean"]
        )
    assert snapshot(folder) == finished
    assert job_state(folder).state == "done"


def test_a_folder_that_another_job_took_after_the_plan_is_left_alone(data, tmp_path):
    """The folder now holds another job (written by another olatbench version or config after this
    plan): this job fails with one line naming the folder and --force, and writes nothing into
    it."""
    out = tmp_path / "runs"
    job = plan(data, out, scenes=["Alpha"])[0]
    other = type(job)(**{**job.__dict__, "config": {**job.config, "lr": 0.2}, "id": ""}).with_id()
    assert other.folder == job.folder and other.id != job.id
    assert run_job(other, progress=False).status == "done"
    before = snapshot(Path(job.folder))
    outcome = run_job(job, progress=False)
    assert outcome.status == "failed" and not outcome.recorded
    assert (
        str(job.folder) in outcome.error
        and "--force" in outcome.error
        and other.id in outcome.error
    )
    assert snapshot(Path(job.folder)) == before


def test_force_still_retrains_a_finished_job(data, tmp_path):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    log = job_folder(out) / "log.txt"
    assert log.read_text().count("job ") == 1
    forced = run_cli(*run_args(data, out, "--scenes", "Alpha", "--force"))
    assert forced.exit_code == 0 and "0 already done, 1 to run" in forced.output, forced.output
    # a new folder, trained again
    assert log.read_text().count("job ") == 1 and "resumed" not in log.read_text()


# ---- a scene's inputs changed mid-run: --keep-finished (#58) -------------------------------------


def test_after_a_scene_changed_keep_finished_keeps_finished_jobs_and_reruns_the_rest(
    data, tmp_path
):
    """Seed 0 finished, seed 1 interrupted; then the scene's points3d.ply changes (it is part of the
    scene's data): both folders hold jobs of the old inputs. The rerun refuses and names
    --keep-finished, which keeps the finished job byte for byte and reruns the unfinished one under
    the new id; --force is still the way to retrain both."""
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha", "--seeds", "2")).exit_code == 0
    finished, unfinished = job_folder(out, seed=0), job_folder(out, seed=1)
    # seed 1 as a run interrupted after its last checkpoint leaves it
    for name in ("DONE", "results.json"):
        (unfinished / name).unlink()
    (data / "Alpha" / "points3d.ply").write_bytes(
        b"ply\nformat ascii 1.0\nelement vertex 0\nend_header\n"
    )
    before = snapshot(finished)

    refused = run_cli(*run_args(data, out, "--scenes", "Alpha", "--seeds", "2"))
    assert refused.exit_code == 2 and "--keep-finished" in refused.output, refused.output
    assert snapshot(finished) == before

    kept = run_cli(*run_args(data, out, "--scenes", "Alpha", "--seeds", "2", "--keep-finished"))
    assert (
        kept.exit_code == 0
        and "kept 1 finished job(s)" in kept.output
        and str(finished) in kept.output
    ), kept.output
    assert snapshot(finished) == before  # the finished job, untouched
    (planned,) = [job for job in plan(data, out, scenes=["Alpha"], seeds=2) if job.seed == 1]
    # the unfinished one, rerun under the new inputs
    assert job_state(unfinished, planned.id).state == "done"


# ---- rigs the canonical frame cannot fit (#58) ---------------------------------------------------


def _gl_pose(eye, target) -> list[list[float]]:
    from datasets_trees import gl_look_at

    return gl_look_at(eye, target).tolist()


def _ring(index: int, radius: float = 1.0) -> np.ndarray:
    angle = index * np.pi / 2
    return radius * np.array([np.cos(angle), np.sin(angle), 0.2])


UNFIT_RIGS = {  # name: (the pose of training frame i, OpenGL camera-to-world; what the error says)
    "one pose": (
        lambda i: _gl_pose([0.0, -4.0, 1.0], [0.0, 0.0, 0.0]),
        "all 4 training cameras have one pose",
    ),
    "one point (a panorama)": (lambda i: _gl_pose([0.0, 0.0, 0.0], _ring(i)), "sit at one point"),
    "looking outwards": (
        lambda i: _gl_pose(_ring(i, 4.0), _ring(i, 8.0)),
        "meet behind or among them",
    ),
    "facing one way, no near/far": (
        lambda i: _gl_pose([0.3 * i, -4.0, 0.1 * i], [0.3 * i, 0.0, 0.1 * i]),
        "face one way",
    ),
}


def _set_rig(scene: Path, pose, **meta_keys) -> None:
    path = scene / "transforms_train.json"
    meta = json.loads(path.read_text())
    meta.update(meta_keys)
    for index, frame in enumerate(meta["frames"]):
        frame["transform_matrix"] = pose(index)
    path.write_text(json.dumps(meta))


@pytest.mark.parametrize("rig", list(UNFIT_RIGS))
def test_a_rig_the_canonical_frame_cannot_fit_is_refused_before_training(data, tmp_path, rig):
    pose, phrase = UNFIT_RIGS[rig]
    _set_rig(data / "Alpha", pose)
    out = tmp_path / "runs"
    result = run_cli(*run_args(data, out, "--scenes", "Alpha"))
    assert_one_clear_error(result, 2, "Alpha", phrase, "Rigs olatbench can fit")
    assert not list(out.rglob("job.json"))  # nothing planned, nothing trained


def test_a_forward_facing_rig_with_its_depth_range_is_fitted_and_runs(data, tmp_path):
    _set_rig(
        data / "Alpha",
        UNFIT_RIGS["facing one way, no near/far"][0],
        camera_near=2.0,
        camera_far=6.0,
    )
    out = tmp_path / "runs"
    result = run_cli(*run_args(data, out, "--scenes", "Alpha"))
    assert result.exit_code == 0, result.output
    assert job_state(job_folder(out)).state == "done"
    from olatbench.bench.views import job_frame
    from olatbench.datasets import load_scene

    (job,) = plan(data, out, scenes=["Alpha"])
    cameras = load_scene(job.scene_path, format=job.scene_format).split(job.train_split)
    # (2+6)/2 ahead
    centre = np.mean([frame.camera.position for frame in cameras], axis=0) + np.array(
        [0.0, 4.0, 0.0]
    )
    np.testing.assert_allclose(job_frame(cameras, job).points(centre), np.zeros(3), atol=1e-9)


# ---- a point cloud whose header declares more points than the file holds (#58) -------------------

HUGE_POINT_CLOUDS = {  # name: (file, what the error says)
    "10^9 points, ascii": (
        b"ply\nformat ascii 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\n"
        b"property float z\nend_header\n0 0 0\n",
        "1,000,000,000 'vertex' elements",
    ),
    "10^14 points, binary": (
        b"ply\nformat binary_little_endian 1.0\nelement vertex 100000000000000\n"
        b"property float x\nproperty float y\nproperty float z\nend_header\n" + bytes(12),
        "100,000,000,000,000 'vertex' elements",
    ),
}


@pytest.mark.parametrize("cloud", list(HUGE_POINT_CLOUDS))
def test_a_point_cloud_declaring_too_many_points_fails_its_job_naming_the_file(
    data, tmp_path, cloud
):
    content, phrase = HUGE_POINT_CLOUDS[cloud]
    path = tmp_path / "huge.ply"
    path.write_bytes(content)
    out = tmp_path / "runs"
    result = run_cli(
        "run",
        "-m",
        "3dgs",
        "-s",
        "tiny",
        "--scenes",
        "Alpha",
        "--data-root",
        data,
        "--out",
        out,
        "--quiet",
        "--device",
        "cpu",
        "--iterations",
        "2",
        "--init-points",
        path,
    )
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output and "MemoryError" not in result.output, result.output
    (failed,) = [line for line in result.output.splitlines() if line.startswith("FAILED")]
    assert str(path) in failed and phrase in failed, failed


# ---- --jobs 2: a worker killed, the main process terminated (#48 item 2) -------------------------

WORKER_DEATHS = ("SIGKILL", "SIGSEGV", "exit")


@pytest.mark.parametrize("death", WORKER_DEATHS)
def test_a_killed_worker_fails_its_own_job_only(data, tmp_path, death):
    """One of three jobs on two workers dies mid-training (the OOM killer's SIGKILL, a crash, an
    exit from a library): that job alone fails, saying how its worker died; the sibling running
    beside it and the job queued after it finish; the killed job resumes on the next run."""
    from olatbench.bench.executors import run_local

    out = tmp_path / "runs"
    jobs = plan(data, out, seeds=2, options=PlanOptions(checkpoint_every=2))[:3]
    dying = type(jobs[0])(
        **{**jobs[0].__dict__, "config": {**jobs[0].config, "die_at_step": 5, "die_by": death}}
    )
    outcomes = run_local([dying, *jobs[1:]], workers=2, progress=False)
    assert [outcome.status for outcome in outcomes] == ["failed", "done", "done"], outcomes
    how = "exit code 3" if death == "exit" else f"killed by signal {death}"
    assert f"worker process died ({how})" in outcomes[0].error and not outcomes[0].recorded
    state = job_state(jobs[0].folder, jobs[0].id)
    assert state.state == "partial" and state.step == 4, state
    assert run_local(jobs[:1], workers=2, progress=False)[0].status == "done"
    assert "resumed from step_00000004.pt" in (Path(jobs[0].folder) / "log.txt").read_text()


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux /proc)."""
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(child) for child in path.read_text().split()] if path.exists() else []


@pytest.mark.skipif(
    not Path("/proc/self/task").is_dir(), reason="finds the worker processes through Linux /proc"
)
def test_sigterm_to_olatbench_run_jobs_2_stops_its_workers_and_releases_the_locks(data, tmp_path):
    """SIGTERM to the main process of ``olatbench run --jobs 2`` while both workers train: it stops
    them and exits 143; no process of the run is left, no lock held, both jobs are partial (nothing
    finished behind its back), and the same command finishes them."""
    out = tmp_path / "runs"
    script = (
        f"import sys; sys.path.insert(0, {str(support.TESTS)!r}); import test_runner_support as "
        "support; from olatbench.datasets import suites; suites.SUITES['tiny'] = "
        "support.tiny_suite(); from olatbench.cli import main; main(sys.argv[1:])"
    )
    argv = [
        str(arg)
        for arg in run_args(
            data, out, "--jobs", "2", "--iterations", "1000", "--checkpoint-every", "2"
        )
    ]
    output = tmp_path / "output.txt"  # not a pipe: a process the run left behind would hold it open
    with open(output, "w") as handle:
        process = subprocess.Popen(
            [sys.executable, "-c", script, *argv],
            stdout=handle,
            stderr=subprocess.STDOUT,
            env={**os.environ, support.STEP_SLEEP_ENV: "0.2"},
        )
    folders = [
        job_folder(out, scene, variant="default~iterations=1000") for scene in ("Alpha", "Beta")
    ]
    children: list[int] = []
    try:
        wait_until(
            lambda: all(list_checkpoints(folder) for folder in folders),
            "a checkpoint of both jobs",
            process=process,
        )
        children = _children(process.pid)
        # the two workers (and multiprocessing's resource tracker)
        assert len(children) >= 2, children
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=BACKSTOP_SECONDS)
        text = output.read_text()
        assert process.returncode == 143, text
        assert "Interrupted" in text and "Traceback" not in text, text
        wait_until(
            lambda: all(process_gone(child) for child in children),
            "the end of every process of the run",
        )
        for folder in folders:
            assert not is_locked(folder)
            assert job_state(folder).state == "partial"
    finally:  # a failed check leaves no process behind either
        process.kill()
        process.wait()
        for child in children:
            if not process_gone(child):
                os.kill(child, signal.SIGKILL)
    rerun = run_cli(*argv)
    assert rerun.exit_code == 0, rerun.output
    for folder in folders:
        assert "resumed from step_" in (folder / "log.txt").read_text()


# ---- the count -----------------------------------------------------------------------------------

FAULT_COUNT = (
    len(READ_ONLY_CASES)
    + 1
    + len(RESULTS_DAMAGE)
    + len(JOB_FILE_DAMAGE)
    + 1
    + len(CHECKPOINT_DAMAGE)
    + len(GAUSSIAN_STATE_DAMAGE)
    + 1
    + len(FINISHED_ELSEWHERE)
    + 1
    + 1
    + len(UNFIT_RIGS)
    + 1
    + len(HUGE_POINT_CLOUDS)
    + len(WORKER_DEATHS)
    + 1
)
# read-only entry points, full disk, results.json, job.json, report, checkpoints, concurrent,
# finished after the plan, a folder another job took, a scene changed mid-run, rigs that cannot be
# fitted and one that can, point clouds declaring too many points, a worker killed, SIGTERM to the
# main process


def test_the_battery_states_its_fault_count_in_the_docs():
    """docs/guarantees.md says how many runner faults this module checks; the two must agree."""
    text = (ROOT / "docs" / "guarantees.md").read_text(encoding="utf-8")
    assert f"runner fault battery: {FAULT_COUNT} faults" in text, FAULT_COUNT
