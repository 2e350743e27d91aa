"""`olatbench doctor` reports every capability and never crashes on a broken one."""

from click.testing import CliRunner

from olatbench.cli import doctor as doctor_module
from olatbench.cli import main


def test_doctor_lists_every_capability():
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0, result.output
    for name in ("torch", "C++ rasterizer", "Mitsuba", "LPIPS weights", "EXR", "Slurm", "MP4"):
        assert name in result.output


def test_a_failing_check_is_reported_not_raised(monkeypatch):
    def _broken():
        raise RuntimeError("probe exploded")

    monkeypatch.setattr(doctor_module, "CHECKS", (_broken,))
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0
    assert "NO" in result.output and "probe exploded" in result.output
