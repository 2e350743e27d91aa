"""Official implementations as methods of the runner, exercised with stand-in checkouts
(tests/official_standins.py): specs and listing, settings precedence, plan -> run -> results ->
report through a Python interpreter and through a container template, failure, timeout,
interruption, and `olatbench doctor`."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import test_runner_support as support
from click.testing import CliRunner
from datasets_trees import write_gs3_tree, write_nrhints_tree
from official_standins import write_checkout, write_runtime_stub
from waiting import BACKSTOP_SECONDS, process_gone, wait_until

from olatbench.bench.executors import run_inline
from olatbench.bench.plan import PlanError, PlanOptions, make_plan
from olatbench.bench.results import read_results
from olatbench.bench.store import job_state
from olatbench.cli import main
from olatbench.datasets import load_scene, suites
from olatbench.methods.official.settings import (
    SettingsError,
    env_name,
    parse_code_options,
    resolve_settings,
)
from olatbench.methods.registry import builtin_specs, get_spec
from olatbench.methods.spec import import_reference
from olatbench.reports.collect import collect
from olatbench.reports.published import paper_method

RUNNABLE = ("gs3-official", "nrhints-official", "rng-official", "ssdgs-official")
# dB: a stand-in render is its ground truth after 8-bit rounding (a wrong frame scores < 25)
PERFECT_PSNR = 35.0


def suite_of(name: str, fmt: str = "nrhints", scenes: tuple[str, ...] = ("Alpha",)) -> suites.Suite:
    """A tiny suite named like a real one (so the spec's suite arguments apply), fast protocol,
    native size; its background is its scenes' (the format's)."""
    return dataclasses.replace(support.tiny_suite(scenes=scenes), name=name, format=fmt)


def write_data(root: Path, fmt: str = "nrhints", scenes: tuple[str, ...] = ("Alpha",)) -> Path:
    writer = write_gs3_tree if fmt == "gs3" else write_nrhints_tree
    for index, scene in enumerate(scenes):
        writer(root / scene, n_train=3, n_test=3, size=(24, 16), seed=index)
    return root


def plan(method: str, suite: suites.Suite, data: Path, out: Path, **code: str):
    return make_plan(
        method, suite, out, data_root=data, progress=False, options=PlanOptions(code=code)
    )


# ---- specs, listing ------------------------------------------------------------------------------


def test_every_official_spec_is_pinned_and_runnable_or_says_why() -> None:
    official = {name: spec for name, spec in builtin_specs().items() if spec.kind == "official"}
    assert set(official) == {*RUNNABLE, "gigs-official", "tensoir-official", "r3dg-official"}
    for name, spec in official.items():
        code = import_reference(spec.implementation)
        assert code.name == name and spec.source.verified
        pinned = len(spec.source.commit) == 40 and set(spec.source.commit) <= set(
            "0123456789abcdef"
        )
        assert pinned or (spec.source.commit == "unverified" and spec.source.status != "verified")
        assert code.runnable == (name in RUNNABLE) and bool(code.commands) == code.runnable
        assert code.runnable or code.unsupported
    listing = CliRunner().invoke(main, ["methods", "list"])
    assert listing.exit_code == 0
    assert "gs3-official      [official, verified]" in listing.output
    assert "rng-official      [official, verified]" in listing.output
    assert (
        "tensoir-official  [official, verified]" in listing.output
        and "not runnable: " in listing.output
    )
    assert "ssdgs             [native]" in listing.output
    shown = CliRunner().invoke(main, ["methods", "show", "nrhints-official"])
    assert "train: <launcher> main.py {*suite_args} --config.data.path {scene}" in shown.output
    assert (
        "291800d12c474d370ec85f99c4c1180c54b68e37" in shown.output
        and "WANDB_MODE=offline" in shown.output
    )


def test_unsupported_codes_and_missing_settings_are_plan_errors(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    with pytest.raises(PlanError, match="environment maps"):
        plan("tensoir-official", suite_of("tiny"), data, tmp_path / "runs")
    jobs = make_plan(
        "gs3-official",
        suite_of("tiny"),
        tmp_path / "runs",
        data_root=data,
        progress=False,
        generate=False,
    )  # a dry run needs no settings
    assert len(jobs) == 1 and jobs[0].official["checkout"] is None
    with pytest.raises(
        PlanError, match=r"no checkout.*no launcher.*OLATBENCH_GS3_OFFICIAL_CHECKOUT"
    ):
        plan("gs3-official", suite_of("tiny"), data, tmp_path / "runs")
    with pytest.raises(PlanError, match="--code settings are for official implementations"):
        plan("trivial", suite_of("tiny"), data, tmp_path / "runs", checkout=str(tmp_path))


# ---- settings ------------------------------------------------------------------------------------


def test_settings_precedence_options_over_toml_over_environment(tmp_path) -> None:
    environ = {
        env_name("gs3-official", "checkout"): "/env/checkout",
        env_name("gs3-official", "python"): "/env/py",
        env_name("gs3-official", "timeout_minutes"): "5",
    }
    toml = {"gs3-official": {"checkout": "/toml/checkout", "conda_env": "gs3"}}
    settings = resolve_settings("gs3-official", {}, toml, environ)
    assert (settings.checkout, settings.launcher, settings.conda_env, settings.python) == (
        "/toml/checkout",
        "conda_env",
        "gs3",
        None,
    )  # the file's launcher wins over the variable's, as a group
    assert settings.timeout_minutes == 5.0
    assert settings.sources["timeout_minutes"] == "OLATBENCH_GS3_OFFICIAL_TIMEOUT_MINUTES"
    settings = resolve_settings(
        "gs3-official", {"python": "/opt/py", "checkout": "rel/clone"}, toml, environ
    )
    assert (
        settings.launcher == "python"
        and settings.conda_env is None
        and settings.python == "/opt/py"
    )
    assert (
        settings.checkout == str(Path("rel/clone").absolute())
        and settings.sources["checkout"] == "--code"
    )
    assert settings.prefix(tmp_path) == ["/opt/py"]
    assert resolve_settings("gs3-official", {}, {}, {}).configured is False
    with pytest.raises(SettingsError, match="unknown setting pyhton"):
        resolve_settings("gs3-official", {"pyhton": "x"}, {}, {})
    with pytest.raises(SettingsError, match="set one launcher"):
        resolve_settings("gs3-official", {"python": "x", "container": "y"}, {}, {})
    assert parse_code_options(["checkout=/a", "nrhints-official.python=/b"], "gs3-official") == {
        "gs3-official": {"checkout": "/a"},
        "nrhints-official": {"python": "/b"},
    }
    with pytest.raises(SettingsError, match="say which method"):
        parse_code_options(["checkout=/a"])


def test_olatbench_toml_in_the_working_folder_is_read(tmp_path, monkeypatch) -> None:
    (tmp_path / "olatbench.toml").write_text(
        '[official.ssdgs-official]\ncheckout = "clones/ssd"\n'
        'container = "apptainer exec --nv --bind {work} ssd.sif python"\n'
    )
    monkeypatch.chdir(tmp_path)
    settings = resolve_settings("ssdgs-official", environ={})
    assert (
        settings.checkout == str(tmp_path / "clones" / "ssd")
        and settings.sources["container"] == "olatbench.toml"
    )
    assert settings.prefix(Path("/w")) == [
        "apptainer",
        "exec",
        "--nv",
        "--bind",
        "/w",
        "ssd.sif",
        "python",
    ]


def test_settings_stay_out_of_the_job_id_and_flags_enter_it(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "gs3", "gs3-official")
    first = plan(
        "gs3-official",
        suite_of("tiny"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )[0]
    moved = plan(
        "gs3-official",
        suite_of("tiny"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        conda_env="gs3",
    )[0]
    assert first.id == moved.id and first.official != moved.official
    flagged = make_plan(
        "gs3-official",
        suite_of("tiny"),
        tmp_path / "runs",
        data_root=data,
        progress=False,
        overrides={"train_args": ["--densify_grad_threshold", "0.0001"]},
        options=PlanOptions(code={"checkout": str(checkout), "python": sys.executable}),
    )[0]
    assert flagged.id != first.id and flagged.variant.startswith("default~train_args=")


# ---- plan -> run -> results, per spec ------------------------------------------------------------


@pytest.mark.parametrize(
    ("method", "suite_name", "fmt", "expected_args"),
    [
        ("gs3-official", "gs3", "gs3", ["--hdr", "--white_background", "--gamma"]),
        ("gs3-official", "nrhints", "nrhints", ["--cam_opt", "--pl_opt"]),
        ("ssdgs-official", "nrhints", "nrhints", ["--cam_opt", "--opt_pose"]),
        ("ssdgs-official", "tiny", "nrhints", ["--position_lr_max_steps"]),
        ("nrhints-official", "tiny", "nrhints", ["config:nr-hints", "--config.model.end-iter"]),
    ],
)
def test_standin_checkout_runs_end_to_end(tmp_path, method, suite_name, fmt, expected_args) -> None:
    data = write_data(tmp_path / "data", fmt)
    checkout = write_checkout(tmp_path / "checkout", method)
    jobs = plan(
        method,
        suite_of(suite_name, fmt),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [outcome] = run_inline(jobs, progress=False)
    folder = Path(jobs[0].folder)
    assert outcome.status == "done", (folder / "log.txt").read_text()
    results = read_results(folder / "results.json")
    assert results["method_kind"] == "official" and results["status"] == "done"
    official = results["official"]
    assert (
        official["pinned_commit"] == get_spec(method).source.commit and official["commit"] is None
    )
    assert [c["step"] for c in official["commands"]] == [
        s for s, _ in import_reference(get_spec(method).implementation).commands
    ]
    assert all(
        c["exit_code"] == 0 and c["seconds"] > 0 and c["cwd"] == str(checkout)
        for c in official["commands"]
    )
    argv = [arg for c in official["commands"] for arg in c["argv"]]
    assert argv[0] == sys.executable and all(arg in argv for arg in expected_args)
    per_image = results["metrics"]["test"]["per_image"]
    frame_ids = [frame.frame_id for frame in load_scene(data / "Alpha").split("test")]
    assert list(per_image) == frame_ids and len(frame_ids) == 3
    assert all(values["psnr"] > PERFECT_PSNR for values in per_image.values()), per_image
    assert sorted(p.stem for p in (folder / "renders" / "test").iterdir()) == sorted(frame_ids)
    assert (
        results["timing"]["train_seconds"] > 0
        and (folder / "DONE").read_text().strip() == jobs[0].id
    )
    log = (folder / "log.txt").read_text()
    assert "$ (cd " in log and "trained" in log and "official scripts cannot resume" in log
    assert not (folder / "official" / "scene").exists() and (folder / "official" / "model").is_dir()


def test_per_scene_flags_of_the_authors_scripts_reach_their_scenes(tmp_path) -> None:
    """GS³ real_train.sh: Fish densifies until 100K with threshold 0.00012, Pixiu 0.0002 (the
    suite's 0.0001 is replaced, not repeated); NRHints train_real.sh:12: Fish's geometry warm-up;
    other scenes keep the suite's."""
    data = write_data(tmp_path / "data", scenes=("Fish", "Pixiu"))
    argvs = {}
    for method in ("gs3-official", "nrhints-official"):
        checkout = write_checkout(tmp_path / method, method)
        jobs = plan(
            method,
            suite_of("nrhints", scenes=("Fish", "Pixiu")),
            data,
            tmp_path / "runs",
            checkout=str(checkout),
            python=sys.executable,
        )
        assert [o.status for o in run_inline(jobs, progress=False)] == ["done", "done"]
        for job in jobs:
            commands = read_results(Path(job.folder) / "results.json")["official"]["commands"]
            argvs[method, job.scene] = commands[0]["argv"]

    def value(argv: list[str], flag: str) -> str | None:
        assert argv.count(flag) <= 1, argv
        return argv[argv.index(flag) + 1] if flag in argv else None

    assert value(argvs["gs3-official", "Fish"], "--densify_until_iter") == "100000"
    assert value(argvs["gs3-official", "Fish"], "--densify_grad_threshold") == "0.00012"
    assert value(argvs["gs3-official", "Pixiu"], "--densify_until_iter") == "90000"
    assert value(argvs["gs3-official", "Pixiu"], "--densify_grad_threshold") == "0.0002"
    assert (
        value(argvs["nrhints-official", "Fish"], "--config.model.geometry-warmup-end") == "100000"
    )
    assert value(argvs["nrhints-official", "Pixiu"], "--config.model.geometry-warmup-end") is None
    shown = {
        name: CliRunner().invoke(main, ["methods", "show", name]).output
        for name in ("gs3-official", "nrhints-official")
    }
    assert (
        "scene nrhints/Pixiu: train --densify_grad_threshold 0.0002 (real_train.sh:370-400)"
        in shown["gs3-official"]
    )
    assert "scene nrhints/Fish: train --densify_until_iter 100000" in shown["gs3-official"]
    assert (
        "scene nrhints/Fish: train --config.model.geometry-warmup-end 100000 "
        "(scripts/train_real.sh:12)" in shown["nrhints-official"]
    )


def test_a_scene_flag_replaces_the_value_of_the_same_flag() -> None:
    from olatbench.methods.official.code import apply_scene_args

    assert apply_scene_args(
        ["t.py", "--a", "1", "--s", "--b", "2"], ("--b", "3", "--c", "4", "--s", "--d")
    ) == ["t.py", "--a", "1", "--s", "--b", "3", "--c", "4", "--d"]


def test_nrhints_data_gets_the_scenes_bounds_instead_of_the_parsers_3_to_10(tmp_path) -> None:
    """The NRHints parser defaults camera_near/far to 3 and 10 when the first split has none
    (data_parser.py:41-47); the converted scene carries bounds that hold the unit sphere its rays
    are clipped to, from every camera."""
    from olatbench.methods.official.convert import unit_sphere_bounds

    data = write_data(tmp_path / "data")
    source = load_scene(data / "Alpha")
    assert source.split("train")[0].camera.near is None
    checkout = write_checkout(tmp_path / "checkout", "nrhints-official")
    jobs = plan(
        "nrhints-official",
        suite_of("sssgs"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [outcome] = run_inline(jobs, progress=False)
    log = (Path(jobs[0].folder) / "log.txt").read_text()
    assert outcome.status == "done", log
    near, far = unit_sphere_bounds(source.split("train") + source.split("test"))
    distances = [
        np.linalg.norm(f.camera.position) for f in source.split("train") + source.split("test")
    ]
    assert near < min(distances) - 0.99 and far > max(distances) + 0.99 and near > 0
    assert f"zn {near}, zf {far}" in log


def test_frames_with_other_intrinsics_are_refused_for_the_nrhints_parser(tmp_path) -> None:
    """Its parser reads one camera model from transforms_train.json: a test split with other
    intrinsics would be rendered with the train split's, so the job fails with a message naming the
    frames."""
    data = write_data(tmp_path / "data")
    test_file = data / "Alpha" / "transforms_test.json"
    meta = json.loads(test_file.read_text())
    meta["camera_intrinsics"][2] *= 1.5  # fx
    test_file.write_text(json.dumps(meta))
    checkout = write_checkout(tmp_path / "checkout", "nrhints-official")
    jobs = plan(
        "nrhints-official",
        suite_of("tiny"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [outcome] = run_inline(jobs, progress=False)
    assert (
        outcome.status == "failed"
        and "one camera model" in outcome.error
        and "test/" in outcome.error
    )


def test_renders_are_mapped_to_their_frames(tmp_path) -> None:
    """A render written for the wrong frame (the stand-in shifts them) scores far lower: the mapping
    is checked."""
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "gs3-official")
    (checkout / "SHIFT").write_text("")
    jobs = plan(
        "gs3-official",
        suite_of("tiny"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    run_inline(jobs, progress=False)
    per_image = read_results(Path(jobs[0].folder) / "results.json")["metrics"]["test"]["per_image"]
    assert all(values["psnr"] < 25.0 for values in per_image.values()), per_image


def test_renders_of_refined_cameras_are_paired_through_the_file_train_py_saved(tmp_path) -> None:
    """SSD-GS on real data: train.py saves the test cameras in its seeded shuffled order and
    render.py --opt_pose renders them in that order; each render is scored against the frame that
    file names, not by position."""
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "ssdgs-official")
    jobs = plan(
        "ssdgs-official",
        suite_of("nrhints"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [outcome] = run_inline(jobs, progress=False)
    folder = Path(jobs[0].folder)
    assert outcome.status == "done", (folder / "log.txt").read_text()
    saved = next(
        (folder / "official" / "model" / "point_cloud").glob("iteration_*/transforms_test.json")
    )
    order = [entry["file_path"] for entry in json.loads(saved.read_text())["frames"]]
    frame_ids = [frame.frame_id for frame in load_scene(data / "Alpha").split("test")]
    # the shuffle is not the identity
    assert sorted(order) == sorted(frame_ids) and order != frame_ids
    per_image = read_results(folder / "results.json")["metrics"]["test"]["per_image"]
    assert all(values["psnr"] > PERFECT_PSNR for values in per_image.values()), per_image


def test_the_refined_sssgs_variant_runs_the_refinement_flags_and_is_the_w_opt_row(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "ssdgs-official")
    plain, refined = make_plan(
        "ssdgs-official",
        suite_of("sssgs"),
        tmp_path / "runs",
        data_root=data,
        progress=False,
        variants=["default", "opt"],
        options=PlanOptions(code={"checkout": str(checkout), "python": sys.executable}),
    )
    outcomes = run_inline([plain, refined], progress=False)
    assert [o.status for o in outcomes] == ["done", "done"]
    rows = {}
    for job in (plain, refined):
        results = read_results(Path(job.folder) / "results.json")
        argv = [arg for c in results["official"]["commands"] for arg in c["argv"]]
        assert all(
            values["psnr"] > PERFECT_PSNR
            for values in results["metrics"]["test"]["per_image"].values()
        )
        # recorded by the official runner
        fitted = results["evaluation"]["test_pose_fitting"] is not None
        rows[job.variant] = (
            paper_method(job.method, job.variant, "sssgs", fitted=fitted),
            "--cam_opt" in argv,
            "--opt_pose" in argv,
        )
    assert rows == {
        "default": ("Ours (w/o Opt)", False, False),
        "opt": ("Ours (w/ Opt)", True, True),
    }


def test_a_render_order_file_that_names_a_stranger_is_refused(tmp_path) -> None:
    from olatbench.methods.official.convert import pair_renders
    from olatbench.methods.official.process import OfficialRunError
    from olatbench.methods.official.specs import SSDGS_CODE

    order = tmp_path / "transforms_test.json"
    order.write_text(
        json.dumps(
            {"frames": [{"file_path": "b", "img_path": "/x/test/b.png"}, {"file_path": "a"}]}
        )
    )
    paired = pair_renders(SSDGS_CODE, order, ["a", "b"], {"model": "/m", "iterations": 7})
    assert paired == {
        "a": Path("/m/test/ours_7/renders/00001.png"),
        "b": Path("/m/test/ours_7/renders/00000.png"),
    }
    with pytest.raises(OfficialRunError, match=r"left out, e\.g\. c"):
        pair_renders(SSDGS_CODE, order, ["a", "b", "c"], {"model": "/m", "iterations": 7})
    order.write_text(json.dumps({"frames": [{"file_path": "./test/z"}]}))
    with pytest.raises(OfficialRunError, match="names 'z', no test frame"):
        pair_renders(SSDGS_CODE, order, ["a"], {"model": "/m", "iterations": 7})


# ---- container template, CLI, report beside a native method --------------------------------------


def test_cli_run_through_a_container_template_and_report_beside_native(
    tmp_path, monkeypatch
) -> None:
    monkeypatch.setitem(suites.SUITES, "tiny", suite_of("tiny", scenes=("Alpha", "Beta")))
    data = write_data(tmp_path / "data", scenes=("Alpha", "Beta"))
    checkout = write_checkout(tmp_path / "checkout", "gs3-official")
    stub = write_runtime_stub(tmp_path / "bin" / "fake-docker")
    template = (
        f"{stub} run --rm --gpus all -v {{checkout}}:{{checkout}} -v {{work}}:{{work}} -w "
        "{checkout} olatbench/official:test python"
    )
    (tmp_path / "olatbench.toml").write_text(
        f"[official.gs3-official]\ncheckout = \"{checkout}\"\ncontainer = '{template}'\n"
    )
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    dry = runner.invoke(
        main, ["run", "-m", "gs3-official", "-s", "tiny", "--data-root", str(data), "--dry-run"]
    )
    assert dry.exit_code == 0 and "2 job(s)" in dry.output
    result = runner.invoke(
        main,
        [
            "run",
            "-m",
            "gs3-official",
            "-s",
            "tiny",
            "--data-root",
            str(data),
            "-q",
            "--device",
            "cpu",
        ],
    )
    assert result.exit_code == 0, result.output
    invocations = (stub.parent / "invocations.txt").read_text().splitlines()
    assert len(invocations) == 4 and all(
        "--gpus all" in line and "olatbench/official:test python" in line for line in invocations
    )
    native = runner.invoke(
        main,
        ["run", "-m", "trivial", "-s", "tiny", "--data-root", str(data), "-q", "--device", "cpu"],
    )
    assert native.exit_code == 0, native.output
    frame = collect(tmp_path / "runs")
    assert set(frame["method"]) == {"trivial", "gs3-official"}
    report = runner.invoke(
        main, ["report", "runs", "--suite", "tiny", "--format", "markdown", "--splits", "test"]
    )
    assert report.exit_code == 0, report.output
    assert "gs3-official" in report.output and "trivial" in report.output
    results = read_results(next((tmp_path / "runs").rglob("gs3-official/**/results.json")))
    assert results["official"]["settings"]["sources"]["container"] == "olatbench.toml"
    assert (
        paper_method("gs3-official", "default", "gs3")
        == paper_method("gs3", "default", "gs3")
        is not None
    )


# ---- failure, timeout, interruption --------------------------------------------------------------


def test_a_failing_command_fails_its_job_and_the_plan_goes_on(tmp_path) -> None:
    data = write_data(tmp_path / "data", scenes=("Alpha", "Beta"))
    checkout = write_checkout(tmp_path / "checkout", "gs3-official")
    # only the job whose command line names the scene Alpha
    (checkout / "FAIL").write_text("/Alpha/")
    jobs = plan(
        "gs3-official",
        suite_of("tiny", scenes=("Alpha", "Beta")),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    outcomes = run_inline(jobs, progress=False)
    assert [o.status for o in outcomes] == ["failed", "done"]
    failed = Path(jobs[0].folder)
    results = read_results(failed / "results.json")
    assert results["status"] == "failed" and results["method_kind"] == "official"
    assert results["official"]["commands"][0]["exit_code"] == 3
    message = results["error"]["message"]
    assert (
        "exit code 3" in message
        and "CUDA out of memory" in message
        and "training line 39" in message
    )
    assert "training line 5\n" not in message  # the tail only
    state = job_state(failed, jobs[0].id)
    assert state.state == "failed" and "train failed with exit code 3" in state.message


def test_a_command_over_its_time_limit_is_stopped(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "gs3-official")
    # ends only when stopped (or the test would hang)
    (checkout / "SLOW").write_text(str(BACKSTOP_SECONDS))
    jobs = plan(
        "gs3-official",
        suite_of("tiny"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
        timeout_minutes="0.03",
    )
    [outcome] = run_inline(jobs, progress=False)
    assert outcome.status == "failed" and "timed out after 0.03 min" in outcome.error
    # absent when a busy machine had not started the command's Python by the limit
    started = checkout / "started"
    if started.is_file() and started.read_text().strip().isdigit():
        wait_until(lambda: process_gone(int(started.read_text())), "end of the stopped command")
    commands = read_results(Path(jobs[0].folder) / "results.json")["official"]["commands"]
    # render never ran: no exit code either
    assert commands[0]["exit_code"] is None and len(commands) == 2
    assert commands[1]["exit_code"] is None and commands[1]["seconds"] is None


def test_an_interrupted_job_reruns_its_commands_from_the_start(tmp_path) -> None:
    """Waits on events only (the train command's pid file, the runner's exit, the command's process
    gone), each with a generous backstop, so a busy machine makes it slower, never red."""
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "gs3-official")
    (checkout / "SLOW").write_text(str(BACKSTOP_SECONDS))  # sleeps until interrupted
    # Ctrl-C's KeyboardInterrupt even when this test runs as a background job of a non-interactive
    # shell, which starts it with SIGINT ignored (POSIX) and Python then keeps it ignored: the
    # runner would never see the signal
    script = (
        f"import sys; sys.path[:0] = {[str(Path(__file__).parent)]!r}\nimport signal; "
        "signal.signal(signal.SIGINT, signal.default_int_handler)\nimport test_runner_support, "
        "dataclasses\nfrom olatbench.datasets import suites\nfrom olatbench.cli import "
        "main\nsuites.SUITES['tiny'] = "
        "dataclasses.replace(test_runner_support.tiny_suite(scenes=('Alpha',)))\nmain()\n"
    )
    argv = [
        sys.executable,
        "-c",
        script,
        "run",
        "-m",
        "gs3-official",
        "-s",
        "tiny",
        "--data-root",
        str(data),
        "--out",
        str(tmp_path / "runs"),
        "-q",
        "--device",
        "cpu",
        "--code",
        f"checkout={checkout}",
        "--code",
        f"python={sys.executable}",
    ]
    process = subprocess.Popen(
        argv, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    pid = None
    try:
        started = checkout / "started"
        pid = wait_until(
            lambda: (
                started.is_file()
                and started.read_text().strip().isdigit()
                and int(started.read_text())
            ),
            "pid file of the official train command",
            process=process,
        )
        process.send_signal(signal.SIGINT)
        output, _ = process.communicate(timeout=BACKSTOP_SECONDS)
        assert process.returncode == 130, output
        wait_until(
            lambda: process_gone(pid), "end of the official command, which stops with the runner"
        )
    finally:
        if process.poll() is None:
            process.kill()
        if pid is not None and not process_gone(pid):
            os.kill(pid, signal.SIGKILL)
    folder = next((tmp_path / "runs").rglob("seed0"))
    state = job_state(folder)
    assert state.state == "partial" and "cannot resume" in state.message
    status = CliRunner().invoke(main, ["status", str(tmp_path / "runs")])
    assert "partial" in status.output and "cannot resume" in status.output
    (checkout / "SLOW").unlink()
    rerun = subprocess.run(
        argv, cwd=tmp_path, capture_output=True, text=True, timeout=BACKSTOP_SECONDS
    )
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    assert (folder / "log.txt").read_text().count("train.py -s") == 2  # the train command ran again
    assert job_state(folder).state == "done"


# ---- doctor --------------------------------------------------------------------------------------


def test_doctor_checks_each_configured_checkout(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    for name in RUNNABLE:
        for key in ("checkout", "python", "conda_env", "container"):
            monkeypatch.delenv(env_name(name, key), raising=False)
    result = CliRunner().invoke(main, ["doctor"])
    assert (
        result.exit_code == 0
        and "official implementations" in result.output
        and "none configured" in result.output
    )
    checkout = write_checkout(tmp_path / "clone", "gs3-official", git=True)
    commit = subprocess.run(
        ["git", "-C", str(checkout), "rev-parse", "HEAD"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    result = CliRunner().invoke(
        main,
        [
            "doctor",
            "--code",
            f"gs3-official.checkout={checkout}",
            "--code",
            f"gs3-official.python={sys.executable}",
            "--code",
            f"nrhints-official.checkout={tmp_path / 'missing'}",
        ],
    )
    lines = result.output.splitlines()
    row = next(line for line in lines if "gs3-official: checkout" in line)
    assert row.strip().startswith("NO") and commit[:12] in row and "pinned 83c8daa41284" in row
    assert (
        "git -C" in lines[lines.index(row) + 1]
        and "checkout 83c8daa4" in lines[lines.index(row) + 1]
    )
    interpreter = next(line for line in lines if "gs3-official: interpreter" in line)
    assert (
        interpreter.strip().startswith("ok") and f"Python {sys.version.split()[0]}" in interpreter
    )
    gpu = next(line for line in lines if "gs3-official: GPU" in line)
    import torch

    assert gpu.strip().startswith("ok" if torch.cuda.is_available() else "NO")
    missing = next(line for line in lines if "nrhints-official: checkout" in line)
    assert (
        missing.strip().startswith("NO") and "no checkout" not in missing and "missing" in missing
    )


# ---- module layout -------------------------------------------------------------------------------


def test_official_job_runner_does_not_import_the_in_process_runner() -> None:
    """bench.official and bench.execute share result writing and scoring through bench.outcome, not
    each other (no import cycle; an official job needs no torch)."""
    code = (
        "import sys, olatbench.bench.official; "
        "print(sorted(m for m in ('olatbench.bench.execute', 'torch') if m in sys.modules))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])},
    )
    assert done.stdout.strip() == "[]", done.stdout + done.stderr
