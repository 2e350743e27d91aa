"""Every module of the package explains itself in a module docstring, and only that: the rest is in
docs/."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "olatbench"
# docs/architecture.md, "Code style": what the module is for and where its detail lives, in at most
# 40 lines.
MAX_LINES = 40


def _docstrings() -> dict[str, str | None]:
    return {
        str(path.relative_to(ROOT)): ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        for path in sorted(PACKAGE.rglob("*.py"))
    }


def test_every_module_has_a_docstring() -> None:
    missing = [path for path, doc in _docstrings().items() if not doc or not doc.strip()]
    assert not missing, f"modules without a docstring: {missing}"


def test_module_docstrings_are_short() -> None:
    long = {
        path: doc.count("\n") + 1
        for path, doc in _docstrings().items()
        if doc and doc.count("\n") + 1 > MAX_LINES
    }
    assert not long, (
        f"module docstrings longer than {MAX_LINES} lines (move the detail to docs/): {long}"
    )
