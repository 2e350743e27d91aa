"""The examples run: numpy-only loaders, a DataLoader, and an external method package found through
the ``olatbench.methods`` entry point by ``olatbench run`` in a fresh process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from datasets_trees import write_nrhints_tree
from waiting import BACKSTOP_SECONDS

from olatbench.bench.results import read_results

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run(args: list[str], env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, timeout=BACKSTOP_SECONDS, env=env)


def test_numpy_only_loader_example(tmp_path):
    write_nrhints_tree(tmp_path / "scene", n_train=3, n_test=1)
    result = _run([sys.executable, str(EXAMPLES / "loaders_numpy.py"), str(tmp_path / "scene")])
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("mean linear radiance") == 3


def test_dataloader_example(tmp_path):
    write_nrhints_tree(tmp_path / "scene", n_train=4, n_test=1, size=(16, 12))
    result = _run(
        [sys.executable, str(EXAMPLES / "loaders_torch_dataloader.py"), str(tmp_path / "scene")]
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[0] == "(2, 12, 16, 3) (2, 3, 3) (2, 3)"


def test_external_method_package_runs_through_its_entry_point(tmp_path):
    # what `pip install examples/external_method` records: a dist-info with the entry point
    site = tmp_path / "site"
    dist = site / "olatbench_example_method-0.1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: olatbench-example-method\nVersion: 0.1.0\n"
    )
    project = (EXAMPLES / "external_method" / "pyproject.toml").read_text()
    entry = next(line for line in project.splitlines() if line.startswith("mean-image"))
    (dist / "entry_points.txt").write_text("[olatbench.methods]\n" + entry.replace('"', "") + "\n")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(site), str(EXAMPLES / "external_method")]),
    }

    listed = _run([sys.executable, "-m", "olatbench.cli", "methods", "list"], env)
    assert listed.returncode == 0 and "mean-image" in listed.stdout, listed.stderr

    write_nrhints_tree(tmp_path / "data" / "Pixiu", n_train=3, n_test=2, size=(64, 48))
    run = _run(
        [
            sys.executable,
            "-m",
            "olatbench.cli",
            "run",
            "--method",
            "mean-image",
            "--suite",
            "nrhints",
            "--scenes",
            "Pixiu",
            "--data-root",
            str(tmp_path / "data"),
            "--out",
            str(tmp_path / "runs"),
        ],
        env,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    results_file = next((tmp_path / "runs").rglob("results.json"))
    results = read_results(results_file)
    assert results["job"]["method"] == "mean-image" and results["status"] == "done"
    # learning-free (training_iterations = 0): no step of the suite's 100000, one checkpoint for
    # restore
    assert results["model"]["iterations"] == 0 and results["job"]["config"]["iterations"] == 0
    assert [p.name for p in (results_file.parent / "checkpoints").iterdir()] == ["step_00000000.pt"]
    assert not (results_file.parent / "train_log.jsonl").read_text().strip()
    assert set(results["metrics"]["test"]["per_image"]) == {"000", "001"}
    assert json.dumps(results["metrics"]["test"]["mean"])  # finite, JSON-clean numbers


def test_component_shares_example(tmp_path):
    from trained_jobs import train_tiny_ssdgs

    # every term from step 0: SSS is shaded
    job = train_tiny_ssdgs(tmp_path, iterations=8, schedule="H")
    result = _run([sys.executable, str(EXAMPLES / "component_shares.py"), str(job)])
    assert result.returncode == 0, result.stderr
    header, *rows = result.stdout.splitlines()
    shares = dict(item.split("=") for item in header.split(": ", 1)[1].split())
    assert set(shares) == {"diffuse", "specular", "sss", "S"}
    # H shades SSS and the shadow term
    assert float(shares["sss"]) > 0 and 0 < float(shares["S"]) <= 1
    quantiles = {row.split()[0]: [float(x) for x in row.split()[1:]] for row in rows}
    assert set(quantiles) == {"sigma_s", "sigma_a", "r", "f_sss"}
    assert all(0.05 <= x <= 2.05 for x in quantiles["sigma_s"] + quantiles["sigma_a"])
    assert all(0.1 <= x <= 3.1 for x in quantiles["r"]) and quantiles["f_sss"] == sorted(
        quantiles["f_sss"]
    )
