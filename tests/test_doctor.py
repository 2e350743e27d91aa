"""`olatbench doctor` reports every capability and never crashes on a broken one."""

import importlib

from click.testing import CliRunner

from olatbench.cli import doctor as doctor_module
from olatbench.cli import main


def test_doctor_lists_every_capability():
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0, result.output
    for name in ("torch", "C++ rasterizer", "C++ SSIM loss", "C++ SSD-GS shading", "Mitsuba", "LPIPS weights", "EXR",
                 "Slurm", "MP4"):
        assert name in result.output


def test_a_missing_native_library_says_torch_runs_instead(monkeypatch, tmp_path):
    libraries = [importlib.import_module(module).LIBRARY for module, _ in doctor_module.NATIVE_LIBRARIES]
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("OLATBENCH_CXX", str(tmp_path / "no-such-compiler"))
    for library in libraries:
        library.reset()
    try:
        result = CliRunner().invoke(main, ["doctor"])
    finally:
        for library in libraries:
            library.reset()
    lines = [line for line in result.output.splitlines() if "C++" in line]
    assert len(lines) == 3 and all("NO" in line and "torch code runs instead" in line and "no-such-compiler" in line
                                   for line in lines), result.output


def test_a_failing_check_is_reported_not_raised(monkeypatch):
    def _broken():
        raise RuntimeError("probe exploded")

    monkeypatch.setattr(doctor_module, "CHECKS", (_broken,))
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0
    assert "NO" in result.output and "probe exploded" in result.output
