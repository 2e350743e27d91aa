"""Where an official implementation's code lives and how its commands are launched, per method.

Fields (all optional until a job runs):

- ``checkout``: the user's clone of the repository (commands run with it as working folder);
- the launcher, exactly one of ``python`` (an interpreter of an existing environment), ``conda_env``
  (run through ``conda run -n ENV python``) or ``container`` (a command template that ends with the
  interpreter inside the container, e.g. ``apptainer exec --nv --bind {work} gs3.sif
  python`` or ``docker run --rm --gpus all -v {checkout}:{checkout} -v {work}:{work} -w {checkout}
  gs3 python``; ``{checkout}`` and ``{work}`` (the job's working folder) are filled in);
- ``timeout_minutes``: the limit of each command, a positive number of minutes (none by default);
- ``device``: ``cuda`` (default: the authors' code on its GPU, as written) or ``cpu``: the job runs
  the unmodified code on the CPU with olatbench's stand-ins for its CUDA-only modules put first on
  its ``PYTHONPATH`` (`olatbench.methods.official.cpu_standins`; with a ``python`` or ``conda_env``
  launcher, not a container).

Sources, highest precedence first: ``--code KEY=VALUE`` options (`olatbench run`, `olatbench
doctor`; a key may be qualified ``METHOD.KEY``), the ``[official.METHOD]`` table of
``olatbench.toml`` in the working folder, and environment variables ``OLATBENCH_<METHOD>_<KEY>``
(``OLATBENCH_GS3_OFFICIAL_CHECKOUT``). Each field comes from the highest source that sets it; the
three launcher fields count as one, so a ``python`` on the command line replaces a ``conda_env``
from the file.

Before a job is planned (`CodeSettings.problems`) the checkout must be a folder and a ``python``
launcher must answer as a Python interpreter (`python_version`, which ``olatbench doctor`` asks
every launcher); the plan also refuses a git checkout at another commit than the method's pin
(`pin_problem`).
"""

from __future__ import annotations

import math
import os
import re
import shlex
import subprocess
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from olatbench.project_file import PROJECT_FILE, ProjectFileError, project_tables

TOML_FILE = PROJECT_FILE
LAUNCHERS = ("python", "conda_env", "container")
#: What a launcher is asked to run to show it is a Python interpreter; it answers
#: ``olatbench-python <version>``.
PYTHON_PROBE = "import sys; print('olatbench-python', sys.version.split()[0])"
# s: a plain interpreter (a container's is probed by olatbench doctor only)
PYTHON_PROBE_TIMEOUT = 60.0
FIELDS = ("checkout", *LAUNCHERS, "timeout_minutes", "device")
DEVICES = ("cuda", "cpu")


class SettingsError(ValueError):
    """Settings that cannot be used: unknown key, several launchers, unreadable olatbench.toml."""


@dataclass(frozen=True)
class CodeSettings:
    """The resolved settings of one official method; ``sources`` says where each field came from."""

    method: str
    checkout: str | None = None
    python: str | None = None
    conda_env: str | None = None
    container: str | None = None
    timeout_minutes: float | None = None
    device: str = "cuda"
    # field -> "--code" | "olatbench.toml" | "$VAR"
    sources: Mapping[str, str] = field(default_factory=dict)

    @property
    def configured(self) -> bool:
        """Whether any source set anything for this method."""
        return bool(self.sources)

    @property
    def launcher(self) -> str | None:
        """``python``, ``conda_env`` or ``container``: the one that is set, or None."""
        return next((name for name in LAUNCHERS if getattr(self, name)), None)

    def problems(self) -> list[str]:
        """What keeps a job from running (empty when nothing does)."""
        found = []
        if not self.checkout:
            found.append("no checkout (the folder of your clone of the official repository)")
        elif not Path(self.checkout).is_dir():
            found.append(f"checkout {self.checkout} is not a folder")
        if self.launcher is None:
            found.append(
                "no launcher: set one of python (an interpreter), conda_env (an environment name) "
                "or container (a command template)"
            )
        elif self.python:
            version, answer = python_version([self.python])
            if version is None:
                found.append(
                    f"python={self.python} ({self.sources.get('python', 'set')}) is not a Python "
                    f"interpreter: asked for its version, {answer}"
                )
        if self.device == "cpu" and self.launcher == "container":
            found.append(
                "device=cpu puts olatbench's CPU stand-ins on the job's PYTHONPATH, which a "
                "container does not see: use a python or conda_env launcher"
            )
        return found

    def prefix(self, work: Path) -> list[str]:
        """The arguments put before a command's script: the interpreter, ``conda run`` or the
        container."""
        if self.python:
            return [self.python]
        if self.conda_env:
            return ["conda", "run", "--no-capture-output", "-n", self.conda_env, "python"]
        if self.container:
            checkout = str(self.checkout or ".")
            try:
                return [
                    part.format(checkout=checkout, work=str(work))
                    for part in shlex.split(self.container)
                ]
            except (KeyError, IndexError, ValueError) as error:
                raise SettingsError(
                    f"{self.method}: container template {self.container!r}: {error!r}; it may "
                    f"use {{checkout}} and {{work}}"
                ) from None
        raise SettingsError(f"{self.method}: no launcher configured")

    def to_json(self) -> dict[str, Any]:
        """Plain data for job.json and results.json."""
        data = asdict(self)
        data["sources"] = dict(self.sources)
        return data

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> CodeSettings:
        return cls(**{**data, "sources": dict(data.get("sources", {}))})


def env_name(method: str, key: str) -> str:
    """``OLATBENCH_GS3_OFFICIAL_CHECKOUT`` for (``gs3-official``, ``checkout``)."""
    return "OLATBENCH_" + f"{method}_{key}".upper().replace("-", "_").replace(".", "_")


def read_toml(folder: str | Path | None = None) -> dict[str, dict[str, Any]]:
    """The ``[official.METHOD]`` tables of ``olatbench.toml`` in ``folder`` (the working folder), or
    {}."""
    try:
        return project_tables("official", "[official.gs3-official]", folder)
    except ProjectFileError as error:
        raise SettingsError(str(error)) from None


def parse_code_options(
    items: list[str] | tuple[str, ...], method: str | None = None
) -> dict[str, dict[str, str]]:
    """``["checkout=/src/gs3", "gs3-official.python=/env/bin/python"]`` -> {method: {key: value}};
    an unqualified key belongs to ``method`` (the method being run) and is an error without one."""
    options: dict[str, dict[str, str]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise SettingsError(
                f"--code expects [METHOD.]KEY=VALUE (e.g. checkout=/src/gs-relight), not {item!r}"
            )
        owner, dot, name = key.strip().rpartition(".")
        owner = owner if dot else method
        if owner is None:
            raise SettingsError(f"--code {item}: say which method, e.g. gs3-official.{name}=...")
        options.setdefault(owner, {})[name] = value
    return options


def resolve_settings(
    method: str,
    options: Mapping[str, Any] | None = None,
    toml: Mapping[str, Mapping[str, Any]] | None = None,
    environ: Mapping[str, str] | None = None,
) -> CodeSettings:
    """The settings of ``method`` from ``options`` (its ``--code`` values), then ``toml`` (default:
    read ``olatbench.toml`` in the working folder), then ``environ`` (default: ``os.environ``);
    module docstring."""
    toml = read_toml() if toml is None else toml
    environ = os.environ if environ is None else environ
    layers = [
        ("--code", dict(options or {})),
        (TOML_FILE, dict(toml.get(method, {}))),
        (
            "$" + env_name(method, "*"),
            {
                key: environ[env_name(method, key)]
                for key in FIELDS
                if env_name(method, key) in environ
            },
        ),
    ]
    for source, values in layers[:2]:
        unknown = sorted(set(values) - set(FIELDS))
        if unknown:
            raise SettingsError(
                f"{method}: unknown setting {', '.join(unknown)} ({source}); known: "
                f"{', '.join(FIELDS)}"
            )
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for source, layer in layers:
        launchers = [name for name in LAUNCHERS if layer.get(name) not in (None, "")]
        if len(launchers) > 1:
            raise SettingsError(
                f"{method}: {source} sets {' and '.join(launchers)}; set one launcher"
            )
        for name, value in layer.items():
            if value in (None, "") or name in values:
                continue
            if name in LAUNCHERS and any(other in values for other in LAUNCHERS):
                continue  # a higher source chose the launcher
            values[name] = value
            sources[name] = env_name(method, name) if source.startswith("$") else source
    if "timeout_minutes" in values:
        try:
            minutes = float(values["timeout_minutes"])
        except (TypeError, ValueError):
            minutes = math.nan
        if not (math.isfinite(minutes) and minutes > 0):
            raise SettingsError(
                f"{method}: timeout_minutes must be a positive number of minutes, not "
                f"{values['timeout_minutes']!r} ({sources['timeout_minutes']})"
            )
        values["timeout_minutes"] = minutes
    if "device" in values:
        values["device"] = str(values["device"]).strip().lower()
        if values["device"] not in DEVICES:
            raise SettingsError(
                f"{method}: device must be one of {', '.join(DEVICES)}, not "
                f"{values['device']!r} ({sources['device']})"
            )
    for name in ("checkout", *LAUNCHERS):
        if name in values:
            values[name] = str(values[name])
    # paths are made absolute here: jobs may run in another folder
    for name in ("checkout", "python"):
        if name in values and (name == "checkout" or "/" in values[name]):
            values[name] = str(Path(values[name]).expanduser().absolute())
    return CodeSettings(method=method, sources=sources, **values)


def checkout_commit(checkout: str | Path) -> tuple[str | None, bool | None]:
    """(HEAD commit, whether the work tree has local changes) of a git checkout; (None, None) when
    it is not the top of a repository or git is missing."""
    try:
        head = subprocess.run(
            ["git", "-C", str(checkout), "rev-parse", "--show-toplevel", "HEAD"],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
        lines = head.stdout.split()
        if (
            head.returncode != 0
            or len(lines) != 2
            or Path(lines[0]).resolve() != Path(checkout).resolve()
        ):
            return None, None  # not a repository, or a folder inside another one
        status = subprocess.run(
            ["git", "-C", str(checkout), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None, None
    return lines[1], bool(status.stdout.strip()) if status.returncode == 0 else None


def python_version(
    prefix: list[str],
    cwd: str | Path | None = None,
    env: Mapping[str, str] | None = None,
    timeout: float = PYTHON_PROBE_TIMEOUT,
) -> tuple[str | None, str]:
    """Run `PYTHON_PROBE` through ``prefix`` (an interpreter, or the launcher that ends with one):
    (its Python version, what it answered) when it is a Python interpreter, else (None, what
    happened instead, in words)."""
    try:
        done = subprocess.run(
            [*prefix, "-c", PYTHON_PROBE],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
            env=None if env is None else {**os.environ, **env},
        )
    except OSError as error:
        return None, f"it cannot be started ({error.strerror or error})"
    except subprocess.TimeoutExpired:
        return None, f"it gave no answer within {timeout:g} s"
    match = re.search(r"^olatbench-python (\S+)$", done.stdout, re.MULTILINE)
    if done.returncode == 0 and match:
        return match.group(1), match.group(0)
    lines = (done.stdout + done.stderr).strip().splitlines()
    said = f"answered {lines[-1][:80]!r}" if lines else "answered nothing"
    return None, f"it {said} and exited with code {done.returncode}"


def pin_problem(checkout: str | Path, pinned: str | None) -> str | None:
    """Why the git ``checkout`` is not the code the method is pinned to
    (``pinned``: the full commit), or None: at the pin, no commit pinned, or not a git checkout
    (whose commit is unknown: recorded as such in results.json)."""
    # "unverified": no commit to hold it to
    if not pinned or not re.fullmatch(r"[0-9a-f]{40}", pinned):
        return None
    commit, _dirty = checkout_commit(checkout)
    if commit is None or commit == pinned:
        return None
    return (
        f"checkout {checkout} is at commit {commit[:12]}, not the pinned {pinned[:12]} that "
        f"olatbench's conversion and commands were written for (git -C {checkout} checkout "
        f"{pinned})"
    )
