"""Exit codes, verb by verb: 2 for a usage error (an unknown name, a wrong argument or option,
something the command line must change), 1 when the work failed (a job, a scene that does not
validate, an unreadable file) or a folder holds nothing to show or report (docs/guarantees.md), 0
otherwise."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import test_runner_support as support
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.cli import main
from olatbench.datasets import suites


@pytest.fixture()
def tiny_suite(monkeypatch):
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """An empty folder, a scene, and a run folder with one finished and one failed job
    (made once)."""
    tmp_path = tmp_path_factory.mktemp("exit_codes")
    suites.SUITES["tiny"] = support.tiny_suite()
    data = support.write_tiny_data(tmp_path / "data")
    runs = tmp_path / "runs"
    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(data),
            "-o",
            str(runs),
            "--scenes",
            "Alpha",
            "--variant",
            "default",
            "--variant",
            "fails",
            "-q",
            "--device",
            "cpu",
        ],
    )
    del suites.SUITES["tiny"]
    assert result.exit_code == 1, result.output  # a job failed
    (tmp_path / "empty").mkdir()
    (tmp_path / "exists.json").write_text("{}")
    write_nrhints_tree(tmp_path / "scene", n_train=3, n_test=1, size=(16, 12))
    return {
        "empty": tmp_path / "empty",
        "data": data,
        "runs": runs,
        "scene": tmp_path / "scene",
        "job": runs / "tiny" / "trivial" / "default" / "Alpha" / "seed0",
        "tmp": tmp_path,
    }


# (verb and arguments with {placeholders}, expected exit code, text the message must hold)
CASES = [
    (
        "run -m trivial -s tiny --data-root {data} -o {runs} --scenes Alpha --variant default",
        0,
        "already done",
    ),
    (
        "run -m trivial -s tiny --data-root {data} -o {runs} --scenes Alpha --variant fails",
        1,
        "job(s) failed",
    ),
    ("run -m no-such-method -s tiny --data-root {data}", 2, "unknown method 'no-such-method'"),
    ("run -m trivial -s nope", 2, "unknown suite 'nope'"),
    ("run -m trivial -s tiny --data-root {data} --scenes Gamma", 2, "has no scene 'Gamma'"),
    ("run -m trivial -s tiny --data-root {data} --set nope=1", 2, "no config field nope"),
    ("run -m trivial -s tiny --data-root {data} --variant zzz", 2, "no preset zzz"),
    ("run -m trivial -s tiny --data-root {data} --json", 2, "--json goes with --dry-run"),
    ("status {runs}", 0, "1 done, 1 failed"),
    ("status {empty}", 2, "no job folders"),  # no job below it: a usage error (docs/guarantees.md)
    ("status {runs} -s nope", 2, "unknown suite 'nope'"),
    ("report {runs}", 0, "trivial"),
    # nothing of olatbench's: a usage error
    ("report {empty}", 2, "no job folder and no results.json"),
    ("report {runs} --suite nope", 2, "unknown suite 'nope'"),
    ("report {runs} --methods nope", 2, "--methods: unknown method 'nope'"),
    ("report {runs} --colours red", 2, "three comma-separated numbers"),
    ("render {empty}", 2, "job.json"),
    ("view {empty}", 2, "no job.json"),  # no job below it: a usage error
    ("view {runs} -s nope", 2, "unknown suite 'nope'"),
    # no job folder: a usage error, as for render
    ("export {empty} -o {tmp}/model.ply", 2, "job.json"),
    ("export {empty}", 2, "Missing option '-o'"),
    ("evaluate {job}/renders/test --gt {data}/Alpha --protocol nope", 2, "unknown metric protocol"),
    (
        "evaluate {job}/renders/test --gt {data}/Alpha --protocol test-fast -o {tmp}/m.json",
        0,
        "wrote",
    ),
    (
        "evaluate {job}/renders/test --gt {data}/Alpha --protocol test-fast -o {tmp}/exists.json",
        2,
        "--overwrite",
    ),
    ("evaluate {job}/renders/test --gt {scene} --protocol test-fast -o {tmp}/n.json", 1, ""),
    ("metrics explain nope", 2, "unknown metric protocol"),
    ("metrics list", 0, "olatbench-v1"),
    ("methods show nope", 2, "unknown method 'nope'"),
    ("methods show trivial", 0, "trivial"),
    ("datasets info {empty}", 2, ""),
    ("datasets validate {scene}", 0, ""),
    ("datasets synth --recipe nope -o {tmp}/synth", 2, "unknown recipe 'nope'"),
    ("datasets convert {scene} {tmp}/converted --to nope", 2, ""),
    ("datasets convert {scene} {data}/Beta --to nrhints", 2, "already exists"),
    ("datasets download nope", 2, ""),
    ("weights install --archive {tmp}/missing.tar.gz", 2, ""),
    ("doctor --nope", 2, "No such option"),
]


@pytest.mark.parametrize(
    ("command", "code", "message"), CASES, ids=[case[0].split(" {")[0] for case in CASES]
)
def test_exit_codes(folders, tiny_suite, command, code, message):
    args = [part.format(**folders) for part in command.split()]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == code, result.output
    assert message in result.output and "Traceback" not in result.output


def test_every_verb_is_covered():
    from olatbench.cli import COMMANDS

    assert {case[0].split()[0] for case in CASES} >= set(COMMANDS)


def test_unknown_method_on_mini_exits_2_in_a_fresh_process():
    """The issue's command, as a user types it (a fresh process; mini's data is never generated for
    it)."""
    result = subprocess.run(
        [sys.executable, "-m", "olatbench", "run", "-m", "no-such-method", "-s", "mini"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=Path(__file__).parent,
    )
    assert result.returncode == 2 and "unknown method 'no-such-method'" in result.stderr, (
        result.stderr
    )
