"""CLI conventions: ``--json`` on the listing verbs, ``--quiet`` and ``TQDM_DISABLE``, one spelling
per option (old ones accepted, hidden), ``python -m olatbench``, ``py.typed`` and the version
written once."""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest
import test_runner_support as support
from click.testing import CliRunner
from waiting import BACKSTOP_SECONDS

import olatbench
from olatbench.cli import main
from olatbench.cli.options import show_progress
from olatbench.datasets import suites

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture()
def tiny(tmp_path, monkeypatch):
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())
    return support.write_tiny_data(tmp_path / "data")


def _json(args: list[str]):
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_run_dry_run_json_lists_every_job_with_its_config(tiny, tmp_path):
    plan = _json(
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(tiny),
            "-o",
            str(tmp_path / "runs"),
            "--seeds",
            "2",
            "--set",
            "lr=0.5",
            "--dry-run",
            "--json",
        ]
    )
    assert [(job["scene"], job["seed"]) for job in plan] == [
        ("Alpha", 0),
        ("Alpha", 1),
        ("Beta", 0),
        ("Beta", 1),
    ]
    assert all(
        job["state"] == "pending" and len(job["id"]) == 16 and job["config"]["lr"] == 0.5
        for job in plan
    )
    assert plan[0]["folder"] == "tiny/trivial/default~lr=0.5/Alpha/seed0"
    refused = CliRunner().invoke(
        main, ["run", "-m", "trivial", "-s", "tiny", "--data-root", str(tiny), "--json"]
    )
    assert refused.exit_code == 2 and "--json goes with --dry-run" in refused.output


def test_status_json(tiny, tmp_path):
    runner = CliRunner()
    done = runner.invoke(
        main,
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(tiny),
            "-o",
            str(tmp_path / "runs"),
            "--scenes",
            "Alpha",
            "-q",
        ],
    )
    assert done.exit_code == 0, done.output
    (entry,) = _json(["status", str(tmp_path / "runs"), "--json"])
    assert (
        entry["job"] == "tiny/trivial/default/Alpha/seed0"
        and entry["state"] == "done"
        and len(entry["id"]) == 16
    )


def test_methods_list_and_doctor_json():
    methods = {entry["name"]: entry for entry in _json(["methods", "list", "--json"])}
    assert methods["ssdgs"]["available"] and "components" in methods["ssdgs"]["ablations"]
    assert methods["ssdgs"]["implementation"].startswith("olatbench.methods.ssdgs")
    doctor = _json(["doctor", "--json"])
    names = [check["name"] for check in doctor["checks"]]
    assert "torch" in names and all(isinstance(check["ok"], bool) for check in doctor["checks"])


def test_methods_show_metrics_list_and_evaluate_json(tiny, tmp_path):
    shown = _json(["methods", "show", "trivial", "--json"])
    fields = {field["name"]: field for field in shown["config"]}
    # JSON values, not repr text
    assert fields["lr"]["default"] == 0.1 and fields["iterations"]["default"] == 20
    assert shown["presets"]["ablation-A"] == {"lr": 0.01} and shown["iterations"] is None
    assert shown["ablations"]["components"][0] == "ablation-A"
    protocols = {entry["id"]: entry for entry in _json(["metrics", "list", "--json"])}
    assert (
        protocols["olatbench-v1"]["version"] == 1 and "psnr" in protocols["olatbench-v1"]["metrics"]
    )
    runs = tmp_path / "runs"
    ran = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(tiny),
            "--scenes",
            "Alpha",
            "-o",
            str(runs),
            "-q",
            "--device",
            "cpu",
        ],
    )
    assert ran.exit_code == 0, ran.output
    renders = runs / "tiny" / "trivial" / "default" / "Alpha" / "seed0" / "renders" / "test"
    scored = _json(
        [
            "evaluate",
            str(renders),
            "--gt",
            str(tiny / "Alpha"),
            "--protocol",
            support.FAST_PROTOCOL,
            "-o",
            str(tmp_path / "m.json"),
            "-q",
            "--json",
        ]
    )
    assert scored["kind"] == "evaluate" and isinstance(
        scored["metrics"]["test"]["mean"]["psnr"], float
    )
    assert scored == json.loads((tmp_path / "m.json").read_text())  # what it wrote


def _command(path: list[str]) -> click.Command:
    command, context = main, click.Context(main)
    for name in path:
        command = command.get_command(context, name)
    return command


@pytest.mark.parametrize(
    ("path", "required", "new", "old", "param", "given", "value"),
    [
        (["run"], ["-m", "x", "-s", "y"], "--output", "--out", "out", "r", Path("r")),
        (["run"], ["-m", "x", "-s", "y"], "-o", "--out", "out", "r", Path("r")),
        (["datasets", "download"], ["gs3"], "--data-root", "--root", "root", "r", Path("r")),
        (["datasets", "synth"], [], "--output", "--out", "out_dir", "r", Path("r")),
        (["datasets", "synth"], [], "--resolution", "--res", "res", "64", (64, 64)),
        (["weights", "install"], [], "--output", "--dest", "dest", "r", Path("r")),
    ],
)
def test_new_and_old_option_spellings_parse_alike_and_only_the_new_is_shown(
    path, required, new, old, param, given, value
):
    command = _command(path)
    for spelling in (new, old):
        assert (
            command.make_context(path[-1], [*required, spelling, given]).params[param] == value
        ), spelling
    shown = CliRunner().invoke(main, [*path, "--help"]).output
    assert new in shown and not re.search(rf"{old}\b(?!-)", shown)


def test_quiet_and_tqdm_disable_turn_progress_off(monkeypatch, tmp_path):
    """`datasets download` passes progress=False with --quiet or TQDM_DISABLE=1
    (tqdm's own variable)."""
    from olatbench.datasets.download import fetch

    seen = []

    def fake_download(suite, scene, root, **kwargs):
        seen.append(kwargs["progress"])
        return Path(root) / scene

    monkeypatch.setattr(fetch, "download_scene", fake_download)
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    args = ["datasets", "download", "gs3", "--scenes", "Lego", "--data-root", str(tmp_path)]
    for extra, env in (([], None), (["--quiet"], None), ([], "1"), ([], "0")):
        if env is None:
            monkeypatch.delenv("TQDM_DISABLE", raising=False)
        else:
            monkeypatch.setenv("TQDM_DISABLE", env)
        assert CliRunner().invoke(main, [*args, *extra]).exit_code == 0
    assert seen == [True, False, False, True]
    assert show_progress(False) and not show_progress(True)


@pytest.mark.parametrize(
    "verb",
    [
        ["run"],
        ["evaluate"],
        ["render"],
        ["datasets", "download"],
        ["datasets", "synth"],
        ["datasets", "validate"],
        ["datasets", "convert"],
        ["view"],
    ],
)
def test_every_verb_with_progress_bars_has_quiet(verb):
    assert "--quiet" in CliRunner().invoke(main, [*verb, "--help"]).output


def test_python_dash_m_olatbench():
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    version = subprocess.run(
        [sys.executable, "-m", "olatbench", "--version"],
        capture_output=True,
        text=True,
        env=env,
        timeout=BACKSTOP_SECONDS,
        check=True,
    )
    assert version.stdout.strip() == f"olatbench, version {olatbench.__version__}"
    methods = subprocess.run(
        [sys.executable, "-m", "olatbench", "methods", "list", "--json"],
        capture_output=True,
        text=True,
        env=env,
        timeout=BACKSTOP_SECONDS,
        check=True,
    )
    assert "ssdgs" in {entry["name"] for entry in json.loads(methods.stdout)}
    usage = subprocess.run(
        [sys.executable, "-m", "olatbench", "--help"],
        capture_output=True,
        text=True,
        env=env,
        timeout=BACKSTOP_SECONDS,
        check=True,
    )
    assert usage.stdout.startswith("Usage: olatbench ")


def test_py_typed_is_shipped_and_the_version_is_written_once():
    tomllib = pytest.importorskip("tomllib")
    assert (Path(olatbench.__file__).parent / "py.typed").is_file()
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "olatbench.__version__"}
    assert any(
        "py.typed" in patterns
        for patterns in project["tool"]["setuptools"]["package-data"].values()
    )
    assert importlib.metadata.version("olatbench") == olatbench.__version__
