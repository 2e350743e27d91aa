"""``olatbench.toml``, the project file read from the working folder: ``[official.METHOD]`` tables
(where the authors' code lives, `olatbench.methods.official.settings`) and ``[suites.NAME]`` tables
(a user's own suites, `olatbench.datasets.suites.user_suites`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

PROJECT_FILE = "olatbench.toml"


class ProjectFileError(ValueError):
    """An olatbench.toml that cannot be read or holds a malformed table: names the file and the
    table."""


def project_file_path(folder: str | Path | None = None) -> Path:
    """``olatbench.toml`` in ``folder`` (default: the working folder)."""
    return Path(folder or os.getcwd()) / PROJECT_FILE


def read_project_file(folder: str | Path | None = None) -> dict[str, Any]:
    """The parsed ``olatbench.toml`` of ``folder`` (default: the working folder), or {} when there
    is none."""
    path = project_file_path(folder)
    if not path.is_file():
        return {}
    try:
        import tomllib
    except ImportError:  # Python 3.10
        try:
            import tomli as tomllib  # type: ignore[no-redef]
        except ImportError:
            raise ProjectFileError(
                f"{path}: reading it needs Python 3.11 or: pip install tomli"
            ) from None
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as error:
        raise ProjectFileError(
            f"{path}: not UTF-8 text (byte 0x{error.object[error.start]:02x} at offset "
            f"{error.start}); TOML files are UTF-8"
        ) from None
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ProjectFileError(f"{path}: {error}") from None


def project_tables(
    section: str, example: str, folder: str | Path | None = None
) -> dict[str, dict[str, Any]]:
    """The ``[section.NAME]`` tables of ``olatbench.toml`` as {NAME: table}; a `ProjectFileError`
    when the section is not made of tables (``example`` shows the expected form)."""
    tables = read_project_file(folder).get(section, {})
    if not isinstance(tables, dict) or not all(isinstance(v, dict) for v in tables.values()):
        raise ProjectFileError(
            f"{project_file_path(folder)}: expected tables [{section}.NAME] (e.g. {example})"
        )
    return tables
