"""The documentation site builds with ``mkdocs build --strict``: broken links and stale API
references fail."""

import subprocess
import sys
from pathlib import Path

from waiting import BACKSTOP_SECONDS

ROOT = Path(__file__).resolve().parents[1]


def test_mkdocs_builds_strictly(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "index.html").is_file() and (
        tmp_path / "api" / "datasets" / "index.html"
    ).is_file()


def test_reports_page_example_is_what_the_code_prints():
    """docs/reports.md shows `olatbench report --published-only --table ablation` output; it must
    stay current."""
    from click.testing import CliRunner

    from olatbench.cli import main

    result = CliRunner().invoke(
        main, ["report", "--published-only", "--table", "ablation", "--format", "markdown"]
    )
    assert result.exit_code == 0, result.output
    page = (ROOT / "docs" / "reports.md").read_text()
    table_lines = [line for line in result.output.splitlines() if line.startswith("|")]
    assert len(table_lines) > 10 and all(line in page for line in table_lines)
