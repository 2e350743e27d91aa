"""benchmarks/gpu_check.py on a machine without CUDA: a clear refusal that writes nothing; its
report helpers."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest
import torch

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "benchmarks" / "gpu_check.py"


def load_script():
    spec = importlib.util.spec_from_file_location("gpu_check", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.skipif(
    torch.cuda.is_available(), reason="this machine has CUDA: the refusal cannot be observed"
)
def test_refuses_without_cuda_and_writes_nothing(tmp_path):
    out = tmp_path / "check"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "-o", str(out), "--wheels", str(tmp_path / "none")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert done.returncode == 2, done.stderr
    assert "gpu_check:" in done.stderr and "docs/gpu.md" in done.stderr
    assert ("CPU-only build" in done.stderr) == (torch.version.cuda is None)
    assert "Traceback" not in done.stderr
    assert not out.exists()  # refused before installing or writing anything


def test_junit_counts_and_markdown_summary(tmp_path):
    module = load_script()
    report = tmp_path / "r.xml"
    report.write_text(
        '<testsuites><testsuite name="pytest" tests="7" failures="1" errors="0" skipped="2">'
        "</testsuite></testsuites>"
    )
    counts = module.junit_counts(report)
    assert counts == {"passed": 4, "failed": 1, "errors": 0, "skipped": 2, "report": "r.xml"}
    assert module.junit_counts(tmp_path / "missing.xml")["passed"] == 0
    case = {
        "suite": "gs3",
        "width": 512,
        "height": 512,
        "images": 2000,
        "gaussians": 550000,
        "step_seconds": 0.05,
        "stages": {"raster": 0.01, "shadow": 0.01, "mlp": 0.02, "optim": 0.005, "rest": 0.004},
        "peak_device_gib": 9.5,
        "projected_seconds": 5400.0,
        "render_fps": 71.3,
    }
    summary = {
        "environment": {
            "date": "d",
            "device": "GPU",
            "device_memory_gib": 80.0,
            "driver": "1",
            "cuda": "13",
            "torch": "t",
            "gsplat": "g",
            "olatbench": "o",
            "commit": "c",
        },
        "cuda_tests": {**counts, "marker": "cuda"},
        "syncs": {"error": "RuntimeError: x"},
        "benchmark": {"cases": [case]},
        "failed_steps": ["sync count"],
    }
    text = module.markdown(summary)
    assert "4 passed, 1 failed, 0 errors, 2 skipped" in text
    assert "| gs3 | 512×512 | 2000 | 550000 | 0.050 |" in text and "1.50 h | 71.3 |" in text
    assert "Failed steps: sync count" in text and "synchronisations" not in text


def test_the_sync_count_is_checked_against_the_fake_cuda_dry_run(tmp_path, monkeypatch):
    """Step 5's bound comes from the dry run of the same SSD-GS preset (no GPU needed): a steady
    step with the shadow term on may make 3 syncs (the camera pass's and the light pass's
    tile-intersection counts, the light pass's entry layout), and the dry run finds no violation;
    the summary line quotes both."""
    pytest.importorskip("gsplat")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    module = load_script()
    expected = module.dry_run_expectation()
    assert expected == {"dry_run_allowed_per_step": 3, "dry_run_violations": []}
    summary = {
        "environment": {
            "date": "d",
            "device": "GPU",
            "device_memory_gib": 80.0,
            "driver": "1",
            "cuda": "13",
            "torch": "t",
            "gsplat": "g",
            "olatbench": "o",
            "commit": "c",
        },
        "cuda_tests": {"passed": 1, "failed": 0, "errors": 0, "skipped": 0, "marker": "cuda"},
        "syncs": {"syncs_per_step": 3, "first": [], **expected},
        "benchmark": {"cases": []},
        "failed_steps": [],
    }
    assert (
        "training step: 3 (the fake-CUDA dry run allows 3; its violations: 0)"
        in module.markdown(summary)
    )
