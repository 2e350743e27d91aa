"""The package imports, the CLI answers, and the data layer stays numpy-only."""

import subprocess
import sys

from click.testing import CliRunner

from olatbench.cli import main


def test_cli_help_lists_the_verbs():
    result = CliRunner().invoke(main, ["--help"])
    assert result.exit_code == 0
    for verb in ("datasets", "run", "report", "evaluate"):
        assert verb in result.output


def test_datasets_import_does_not_import_torch():
    code = "import sys, olatbench.datasets; sys.exit(1 if 'torch' in sys.modules else 0)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
