"""The fault battery for files a run writes and a user may edit (#48): each damage gives one clear
error naming the file and the field, the documented exit code, no traceback, and loses nothing.

Faults: a finished job's results.json edited into another shape (`RESULTS_SHAPES`, met by
``status``, ``report``, the viewer and the rerun), a job.json switched to another method (met by
``view``, ``render``, ``export``) or that JSON cannot parse (nested too deep, an integer too long:
met by ``status`` and ``view``), ``export`` to a full or read-only disk, an official job whose
failure meets a full disk, and a run folder with no job in it (met by ``status``, ``report``,
``view``: a usage error, exit 2). The number of faults is `FAULT_COUNT`, stated in
docs/guarantees.md.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import re
import sys
from pathlib import Path

import pytest
import test_runner_support as support
from test_fault_battery_runner import (
    SimulatedFault,
    assert_one_clear_error,
    job_folder,
    run_args,
    run_cli,
)

from olatbench.bench.results import read_results
from olatbench.bench.store import job_state
from olatbench.datasets import suites
from olatbench.viewer.model import ViewerModel

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


@pytest.fixture(autouse=True)
def tiny_suite(monkeypatch):
    """The tiny suite registered as 'tiny' for the CLI."""
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())


# ---- a results.json edited into another shape ----------------------------------------------------


def _edit(change):
    def write(path: Path) -> None:
        data = json.loads(path.read_text())
        change(data)
        path.write_text(json.dumps(data))

    return write


RESULTS_SHAPES = {  # name: (damage, the key the message names)
    "metrics null": (
        _edit(lambda d: d.update(metrics=None)),
        "metrics: expected an object, found null",
    ),
    "metrics a list": (
        _edit(lambda d: d.update(metrics=[1.0])),
        "metrics: expected an object, found a list",
    ),
    "job a number": (_edit(lambda d: d.update(job=5)), "job: expected an object"),
    "job.seed text": (_edit(lambda d: d["job"].update(seed="0")), "job.seed: expected an integer"),
    "mean a list": (
        _edit(lambda d: d["metrics"]["test"].update(mean=[20.0])),
        "metrics.test.mean: expected",
    ),
    "metric value text": (
        _edit(lambda d: d["metrics"]["test"]["mean"].update(psnr="20.5")),
        "metrics.test.mean.psnr: expected a number or null, found text '20.5'",
    ),
    "per-image value text": (
        _edit(lambda d: next(iter(d["metrics"]["test"]["per_image"].values())).update(ssim="high")),
        "metrics.test.per_image.",
    ),
    "status a number": (_edit(lambda d: d.update(status=1)), "status: expected 'done' or 'failed'"),
    "timing a list": (_edit(lambda d: d.update(timing=[])), "timing: expected an object"),
    "model text": (_edit(lambda d: d.update(model="final")), "model: expected an object or null"),
    "nested too deep": (
        lambda path: path.write_text("[" * 100_000 + "]" * 100_000),
        "nested too deeply",
    ),
    "integer too long": (
        lambda path: path.write_text('{"schema_version": ' + "2" * 5000 + "}"),
        "an integer with more digits",
    ),
    "metric value NaN": (  # was reported as "not computed" (#58)
        _edit(lambda d: d["metrics"]["test"]["mean"].update(psnr=float("nan"))),
        "metrics.test.mean.psnr: expected a number or null, found NaN",
    ),
    "metric missing": (  # was reported as "no run found" (#58)
        _edit(lambda d: d["metrics"]["test"]["mean"].pop("psnr")),
        "metrics.test.mean: missing psnr",
    ),
}


@pytest.mark.parametrize("shape", list(RESULTS_SHAPES))
def test_a_results_json_of_another_shape_is_damaged_reported_and_re_evaluated(
    data, tmp_path, shape
):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out)).exit_code == 0
    folder = job_folder(out)
    path = folder / "results.json"
    original = read_results(path)
    damage, phrase = RESULTS_SHAPES[shape]
    damage(path)

    state = job_state(folder)
    assert state.state == "damaged" and str(path) in state.message and phrase in state.message, (
        state.message
    )
    status = run_cli("status", out)
    assert (
        status.exit_code == 0 and "damaged" in status.output and "Traceback" not in status.output
    ), status.output
    report = run_cli("report", out)
    assert report.exit_code == 0 and "Traceback" not in report.output, report.output
    assert f"skipped (unreadable): {path}" in report.stderr and phrase in report.stderr, (
        report.stderr
    )
    assert "Beta" in report.stdout  # the other job's results still make the table
    # the viewer shows the job, without the runner's PSNR
    assert ViewerModel.open(folder)._recorded == {}
    damaged = path.read_bytes()
    rerun = run_cli(*run_args(data, out))
    assert rerun.exit_code == 0 and "1 damaged: re-evaluated" in rerun.output, rerun.output
    assert read_results(path)["metrics"] == original["metrics"]  # nothing lost
    # the edited file too, and said where (#58)
    assert (folder / "results.json.damaged").read_bytes() == damaged
    assert (
        f"kept as {folder / 'results.json.damaged'}" in rerun.output and phrase in rerun.output
    ), rerun.output


# ---- a job.json switched to another method -------------------------------------------------------


def _switch_to_3dgs(folder: Path) -> None:
    """Edit job.json as a user might: another method, its identity edited to match, the config left
    as it was."""
    path = folder / "job.json"
    job = json.loads(path.read_text())
    job["method"] = job["identity"]["method"] = "3dgs"
    job["method_ref"] = "olatbench.methods.baselines.gs3dgs:GaussianSplatting3D"
    path.write_text(json.dumps(job))


SWITCHED_METHOD_ENTRIES = {
    "view": ["view", "{job}", "--port", "0"],
    "render": ["render", "{job}", "--sweep", "light-orbit", "--frames", "2", "-o", "{tmp}/sweep"],
    "export": ["export", "{job}", "-o", "{tmp}/model.ply"],
}


@pytest.mark.parametrize("entry", list(SWITCHED_METHOD_ENTRIES))
def test_a_job_json_switched_to_another_method_is_one_error_naming_the_config(
    data, tmp_path, entry
):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    folder = job_folder(out)
    _switch_to_3dgs(folder)
    argv = [
        arg.replace("{job}", str(folder)).replace("{tmp}", str(tmp_path))
        for arg in SWITCHED_METHOD_ENTRIES[entry]
    ]
    result = run_cli(*argv)
    assert_one_clear_error(
        result, 1, f"{folder / 'job.json'}: config: not a config of method '3dgs'", "'lr'"
    )


JOB_JSON_PARSE_FAULTS = {
    "nested too deep": ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
    "integer too long": ('{"id": ' + "3" * 5000 + "}", "an integer with more digits"),
}


@pytest.mark.parametrize("fault", list(JOB_JSON_PARSE_FAULTS))
def test_a_job_json_that_json_cannot_parse_is_damaged_and_one_error(data, tmp_path, fault):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    folder = job_folder(out)
    text, phrase = JOB_JSON_PARSE_FAULTS[fault]
    (folder / "job.json").write_text(text)
    status = run_cli("status", out)
    assert status.exit_code == 0 and "damaged" in status.output and phrase in status.output, (
        status.output
    )
    assert_one_clear_error(
        run_cli("view", folder, "--port", "0"), 1, f"{folder / 'job.json'} is unreadable", phrase
    )


# ---- export to a full or read-only disk ----------------------------------------------------------


@pytest.fixture(scope="module")
def gaussian_job(tmp_path_factory) -> Path:
    from trained_jobs import train_tiny

    return train_tiny("3dgs", tmp_path_factory.mktemp("export_fault"), iterations=4)


@pytest.mark.parametrize(
    ("code", "reason"),
    [(errno.ENOSPC, "No space left on device"), (errno.EROFS, "Read-only file system")],
)
def test_export_to_a_disk_that_refuses_the_file_is_one_line(
    gaussian_job, tmp_path, monkeypatch, code, reason
):
    target = tmp_path / "out"
    target.mkdir()
    (target / "model.ply").write_bytes(b"the previous export")
    fault = SimulatedFault(monkeypatch, target, code)
    fault.on()
    result = run_cli("export", gaussian_job, "-o", target / "model.ply")
    fault.off()
    assert_one_clear_error(
        result, 1, f"cannot write {target / 'model.ply'}: {reason}", "choose another -o"
    )
    assert (target / "model.ply").read_bytes() == b"the previous export"  # left as it was


# ---- an official job whose failure meets a full disk ---------------------------------------------


def test_an_official_job_failing_on_a_full_disk_reports_the_commands_message_first(
    tmp_path, monkeypatch
):
    """The official command fails (exit code 3), then the disk is full when its error.txt and
    results.json are written: the outcome says the command's failure, and the disk's error after it
    (#48)."""
    from datasets_trees import write_nrhints_tree
    from official_standins import write_checkout

    import olatbench.bench.official as official
    from olatbench.bench.executors import run_inline
    from olatbench.bench.plan import PlanOptions, make_plan

    write_nrhints_tree(tmp_path / "data" / "Alpha", n_train=3, n_test=3, size=(24, 16))
    checkout = write_checkout(tmp_path / "checkout", "gs3-official")
    (checkout / "FAIL").write_text("/Alpha/")
    suite = dataclasses.replace(
        support.tiny_suite(scenes=("Alpha",)), name="tiny", format="nrhints"
    )
    out = tmp_path / "runs"
    (job,) = make_plan(
        "gs3-official",
        suite,
        out,
        data_root=tmp_path / "data",
        progress=False,
        options=PlanOptions(code={"checkout": str(checkout), "python": sys.executable}),
    )
    fault = SimulatedFault(monkeypatch, out, errno.ENOSPC)
    real_failed = official._failed

    def failed_on_a_full_disk(*args, **kwargs):
        fault.on()
        return real_failed(*args, **kwargs)

    monkeypatch.setattr(official, "_failed", failed_on_a_full_disk)
    (outcome,) = run_inline([job], progress=False)
    fault.off()
    assert outcome.status == "failed" and not outcome.recorded
    assert re.match(
        r"train failed with exit code 3.*\(not recorded in the folder: .*No space left on device",
        outcome.error,
    ), outcome.error
    assert not (Path(job.folder) / "error.txt").exists()  # the next run retries the job


# ---- official settings that cannot run: named before the plan (#58) ------------------------------


def _not_python(tmp_path: Path) -> list[str]:
    script = tmp_path / "not-python"
    script.write_text("#!/bin/sh\necho not python\n")
    script.chmod(0o755)
    return [f"python={script}"]


def _other_commit(tmp_path: Path) -> list[str]:
    from official_standins import write_checkout

    return [f"checkout={write_checkout(tmp_path / 'clone', 'gs3-official', git=True)}"]


# name: (--code settings over a good checkout and interpreter, what the error says)
OFFICIAL_SETTINGS_FAULTS = {
    "timeout_minutes=-1": (
        lambda tmp_path: ["timeout_minutes=-1"],
        "timeout_minutes must be a positive number of minutes, not '-1' (--code)",
    ),
    "python that is not Python": (
        _not_python,
        "is not a Python interpreter: asked for its version, it answered 'not python'",
    ),
    "checkout at another commit": (_other_commit, "not the pinned 83c8daa41284"),
}


@pytest.mark.parametrize("fault", list(OFFICIAL_SETTINGS_FAULTS))
def test_official_settings_that_cannot_run_are_refused_before_the_plan_naming_them(tmp_path, fault):
    from datasets_trees import write_nrhints_tree
    from official_standins import write_checkout

    scene = write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=2, size=(24, 16)).root
    settings, phrase = OFFICIAL_SETTINGS_FAULTS[fault]
    code = [
        f"checkout={write_checkout(tmp_path / 'plain', 'gs3-official')}",
        f"python={sys.executable}",
        *settings(tmp_path),
    ]
    out = tmp_path / "runs"
    result = run_cli(
        "run",
        "-m",
        "gs3-official",
        "--data",
        scene,
        "--out",
        out,
        "--quiet",
        *[arg for item in code for arg in ("--code", item)],
    )
    assert_one_clear_error(result, 2, phrase)
    assert not out.exists()  # nothing planned, nothing started
    # the doctor says the same, not "ok ... Python not python"
    if fault == "python that is not Python":
        doctor = run_cli(
            "doctor", *[arg for item in code for arg in ("--code", f"gs3-official.{item}")]
        )
        (row,) = [
            line for line in doctor.output.splitlines() if "gs3-official: interpreter" in line
        ]
        assert row.strip().startswith("NO") and "not a Python interpreter" in row, row


# ---- a render that leaves another's frames, a light path with a negative intensity (#58) ---------


def test_a_second_render_into_a_folder_leaves_only_its_own_frames_and_the_users_files(
    data, tmp_path
):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    videos = tmp_path / "videos"
    first = run_cli("render", job_folder(out), "--orbit", "--frames", "4", "-o", videos, "--quiet")
    assert first.exit_code == 0, first.output
    frames = videos / "orbit_frames"
    (frames / "notes.txt").write_text("mine")  # a file of the user's in the frame folder
    second = run_cli("render", job_folder(out), "--orbit", "--frames", "2", "-o", videos, "--quiet")
    assert second.exit_code == 0, second.output
    assert sorted(path.name for path in frames.iterdir() if not path.name.startswith(".")) == [
        "00000.png",
        "00001.png",
        "notes.txt",
    ]


def test_a_light_path_with_a_negative_intensity_is_refused_naming_the_field(data, tmp_path):
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha")).exit_code == 0
    lights = tmp_path / "lights.json"
    lights.write_text(json.dumps({"lights": [{"position": [0, 0, 4], "intensity": [30, -1, 30]}]}))
    result = run_cli(
        "render",
        job_folder(out),
        "--orbit",
        "--frames",
        "2",
        "--light-path",
        lights,
        "-o",
        tmp_path / "videos",
        "--quiet",
    )
    assert_one_clear_error(result, 2, f"{lights}: lights[0].intensity: must be ≥ 0")
    assert not (tmp_path / "videos" / "orbit.mp4").exists()


# ---- a run folder with no job in it --------------------------------------------------------------

EMPTY_FOLDER_ENTRIES = {
    "status": (["status", "{empty}"], "no job folders (job.json) below"),
    "status --json": (["status", "{empty}", "--json"], "no job folders (job.json) below"),
    "status -s data-nrhints": (
        ["status", "{empty}", "-s", "data-nrhints"],
        "start one with: olatbench run --method ssdgs --data SCENE_FOLDER",
    ),
    "report": (["report", "{empty}"], "no job folder and no results.json below"),
    "view": (["view", "{empty}", "--port", "0"], "no job.json in or below it"),
}


@pytest.mark.parametrize("entry", list(EMPTY_FOLDER_ENTRIES))
def test_a_run_folder_with_no_job_is_a_usage_error(tmp_path, entry):
    empty = tmp_path / "empty"
    (empty / "notes").mkdir(parents=True)  # something, but nothing of olatbench's
    argv, phrase = EMPTY_FOLDER_ENTRIES[entry]
    result = run_cli(*[arg.replace("{empty}", str(empty)) for arg in argv])
    assert_one_clear_error(result, 2, phrase)


def test_a_run_folder_whose_jobs_have_no_results_is_not_a_usage_error(data, tmp_path):
    """Job folders but no results.json (only failed or pending jobs): nothing readable to report,
    exit 1."""
    out = tmp_path / "runs"
    assert run_cli(*run_args(data, out, "--scenes", "Alpha", "--variant", "fails")).exit_code == 1
    for path in out.rglob("results.json"):  # a failed job's record gone too: no results.json at all
        path.unlink()
    assert_one_clear_error(
        run_cli("report", out), 1, "no finished job below", "1 failed", "olatbench status"
    )


# ---- the count -----------------------------------------------------------------------------------

FAULT_COUNT = (
    len(RESULTS_SHAPES)
    + len(SWITCHED_METHOD_ENTRIES)
    + len(JOB_JSON_PARSE_FAULTS)
    + 2
    + 1
    + len(OFFICIAL_SETTINGS_FAULTS)
    + 2
    + len(EMPTY_FOLDER_ENTRIES)
    + 1
)


def test_the_battery_states_its_fault_count_in_the_docs():
    text = (ROOT / "docs" / "guarantees.md").read_text(encoding="utf-8")
    assert f"records fault battery: {FAULT_COUNT} faults" in text, FAULT_COUNT
