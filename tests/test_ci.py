"""CI and the tests' isolation (#48): `.ci/run` runs the README's two set-up commands in order, as
written, and every test runs in its own working directory and cache (tests/conftest.py), so the test
command passes after the main job has written ``runs/`` into the checkout and a calibration into the
user's cache."""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest
from waiting import BACKSTOP_SECONDS

ROOT = Path(__file__).resolve().parents[1]


def readme_setup_commands() -> list[str]:
    """The ```bash blocks of README.md's "Set-up: two commands" section, read here independently of
    .ci/run."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Set-up: two commands\n", 1)[1].split("\n## ", 1)[0]
    return [
        block.strip()
        for block in re.findall(r"^```bash\n(.*?)^```$", section, flags=re.MULTILINE | re.DOTALL)
    ]


def test_ci_runs_the_readme_setup_commands_in_order_as_written():
    commands = readme_setup_commands()
    assert len(commands) == 2
    # main job first
    assert "olatbench run --method ssdgs --suite mini" in commands[0] and "pytest" in commands[1]
    listed = subprocess.run(
        ["bash", str(ROOT / ".ci" / "run"), "--list"],
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
    )
    assert listed.returncode == 0, listed.stderr
    assert listed.stdout.splitlines() == commands
    script = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    # nothing run but what README.md says: each command stands in the script once, as its one list
    assert all(script.count(command) == 1 for command in commands)
    assert (
        script.count("bash -euo pipefail -c") == 1 and 'for command in "${commands[@]}"' in script
    )


SEEN: list[tuple[str, str]] = []


@pytest.mark.parametrize("turn", [1, 2])
def test_each_test_has_its_own_empty_working_directory_and_cache(turn):
    cwd, cache = Path.cwd(), Path(os.environ["XDG_CACHE_HOME"])
    assert cwd != ROOT and ROOT not in cwd.parents and list(cwd.iterdir()) == []
    assert cache != Path.home() / ".cache"
    assert sorted(path.name for path in (cache / "olatbench").iterdir()) == [
        "ext",
        "mini",
        "weights",
    ]
    assert not (cache / "olatbench" / "calibration.json").exists()
    assert all(
        name not in os.environ for name in ("OLATBENCH_DATA", "OLATBENCH_WEIGHTS_DIR", "TORCH_HOME")
    )
    SEEN.append((str(cwd), str(cache)))
    if turn == 2:
        assert SEEN[-2][0] != SEEN[-1][0] and SEEN[-2][1] != SEEN[-1][1]


def test_a_runs_folder_and_a_calibration_where_pytest_starts_change_no_test(tmp_path):
    """The README's order, shortened: a ``runs/`` in the folder pytest starts in and a
    ``calibration.json`` in the cache it starts with (as the main job and any
    ``--dry-run --calibrate`` leave them); the two tests that failed after the main job (#48) still
    pass."""
    start = tmp_path / "checkout"
    (start / "runs" / "mini").mkdir(parents=True)
    user_cache = tmp_path / "user-cache"
    (user_cache / "olatbench").mkdir(parents=True)
    from olatbench.bench.estimate import machine_id

    stored = {machine_id(): {"0" * 64: {"a": 0.5, "b": 0.0, "measured": {"0": 0.5}}}}
    (user_cache / "olatbench" / "calibration.json").write_text(json.dumps(stored))
    env = {**os.environ, "XDG_CACHE_HOME": str(user_cache), "PYTHONPATH": str(ROOT)}
    tests = [
        "tests/test_report_runs.py::test_cli_report_formats",
        "tests/test_method_specs.py::test_ablation_dry_run_imports_no_torch_and_expands_the_specs_grid",
    ]
    result = subprocess.run(
        [
            "python",
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "--rootdir",
            str(ROOT),
            *[str(ROOT / test) for test in tests],
        ],
        cwd=start,
        env=env,
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "2 passed" in result.stdout
