"""Checks of each configured official implementation for ``olatbench doctor``: the checkout exists
and is at the pinned commit (or says which commit it is at), the interpreter runs, and a GPU is
visible from it — or, with ``device=cpu``, that olatbench's stand-ins of that method import there
and the environment holds the authors' pins (`CPU_PINS`, `NRHINTS_CPU_PINS`, `RNG_CPU_PINS`: the
recipes of docs/official.md)."""

from __future__ import annotations

import subprocess
from collections.abc import Mapping
from pathlib import Path

from olatbench.methods.official.code import OfficialCode
from olatbench.methods.official.settings import (
    CodeSettings,
    SettingsError,
    checkout_commit,
    python_version,
    resolve_settings,
)
from olatbench.methods.spec import MethodSpec

Check = tuple[str, bool, str, str]  # name, ok, detail, fix (as olatbench.cli.doctor)
PROBE_TIMEOUT = 300.0  # s: a container image may have to be pulled or started
# The official environment for device=cpu: the authors' requirements.txt pins
# (SSD-GS 26e4251, GS³ 83c8daa) that their code needs on the CPU, and the local CPU build of torch.
# OpenCV: the headless build of their pinned 4.9.0.80.
CPU_PINS = {
    "torch": "2.13.0+cpu",
    "numpy": "1.26.3",
    "PIL": "11.1.0",
    "plyfile": None,
    "cv2": "4.9.0",
    "tqdm": "4.67.1",
    "jaxtyping": None,
}
# NRHints 291800d: the pins of its requirements.txt (lpips is the stand-in; PyMCubes any: its 0.1.2
# does not build against the numpy 2 headers pip builds it with, 0.1.6 does; OpenCV: the headless
# build of 4.8.1.78).
NRHINTS_CPU_PINS = {
    "torch": "2.13.0+cpu",
    "numpy": None,
    "tyro": "0.5.4",
    "torchmetrics": "1.0.0",
    "jaxtyping": "0.2.19",
    "imageio": "2.24.0",
    "cv2": "4.8.1",
    "tensorboardX": "2.5.1",
    "torchinfo": "1.8.0",
    "mcubes": None,
    "trimesh": "3.18.0",
    "einops": None,
    "scipy": None,
    "tqdm": None,
    "wandb": None,
}
# RNG 4e8748e: environment.yml pins python 3.7.13, pytorch 1.12.1 and torchvision 0.13.1 (CUDA 11.6
# builds; here the local CPU torch, and torchvision is a stand-in) and plyfile, tqdm unpinned; its
# code also imports numpy, PIL, cv2 (scene/dataset_readers.py:20), matplotlib (train.py:30) and
# OpenEXR (exr.py:6), which it does not list. Pillow 11.1.0 as for SSD-GS: dataset_readers.py:265
# passes an np.byte array to Image.fromarray(..., "RGB").
RNG_CPU_PINS = {
    "torch": "2.13.0+cpu",
    "numpy": "1.26.3",
    "PIL": "11.1.0",
    "plyfile": None,
    "tqdm": None,
    "cv2": None,
    "matplotlib": None,
    "OpenEXR": None,
}
# the others: CPU_PINS
METHOD_CPU_PINS = {"nrhints-official": NRHINTS_CPU_PINS, "rng-official": RNG_CPU_PINS}
# what the authors import
_PROBE_IMPORTS = {
    "simple_knn": "simple_knn._C",
    "torchvision": "torchvision.utils",
    "torchmetrics": "torchmetrics.functional.image",
}
_CPU_PROBE = (
    "import importlib, importlib.metadata as md, sys\n"
    "for name in STANDINS:\n"
    "    module = importlib.import_module(name)\n"
    "    assert 'cpu_standins' in str(module.__file__), (name, module.__file__)\n"
    "found = {}\n"
    "for name in NAMES:\n"
    "    try:\n"
    "        module = importlib.import_module(name)\n"
    "    except Exception as error:\n"
    "        found[name] = 'missing (' + type(error).__name__ + ')'\n"
    "        continue\n"
    "    try:\n"
    "        found[name] = getattr(module, '__version__', None) or md.version(name)\n"
    "    except md.PackageNotFoundError:\n"
    "        found[name] = 'unknown version'\n"
    "print(repr(found))\n"
)
_GPU_PROBE = (
    "import torch; ok = torch.cuda.is_available(); print(torch.cuda.get_device_name(0) if ok else "
    "'torch sees no CUDA device'); raise SystemExit(0 if ok else 1)"
)


def _probe(
    settings: CodeSettings, code: str, env: Mapping[str, str] | None = None
) -> tuple[int | None, str]:
    """Run ``python -c code`` through the method's launcher in its checkout, with ``env`` added to
    the environment: (exit code, last output line)."""
    import os

    work = Path(str(settings.checkout)).expanduser().resolve()
    try:
        done = subprocess.run(
            [*settings.prefix(work), "-c", code],
            cwd=work,
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT,
            check=False,
            env={**os.environ, **(env or {})},
        )
    except FileNotFoundError as error:
        return None, f"cannot start {error.filename}"
    except subprocess.TimeoutExpired:
        return None, f"no answer within {PROBE_TIMEOUT:g} s"
    lines = (done.stdout + done.stderr).strip().splitlines()
    return done.returncode, lines[-1] if lines else ""


def check_code(spec: MethodSpec, settings: CodeSettings) -> list[Check]:
    """The checks of one configured method (three lines: checkout and commit, interpreter, GPU)."""
    name, pin = spec.name, spec.source
    assert pin is not None
    sources = ", ".join(f"{key} from {source}" for key, source in settings.sources.items())
    problems = settings.problems()
    checkout = Path(settings.checkout).expanduser() if settings.checkout else None
    if checkout is None or not checkout.is_dir():
        return [
            (
                f"{name}: checkout",
                False,
                problems[0] + f" ({sources})",
                f"git clone https://github.com/{pin.repository} <folder> && git -C <folder> "
                f"checkout {pin.commit}; then set checkout (olatbench.toml [official.{name}])",
            )
        ]
    commit, dirty = checkout_commit(checkout)
    if commit is None:
        rows = [
            (
                f"{name}: checkout",
                False,
                f"{checkout} is not a git checkout, so its commit is unknown "
                f"(pinned: {pin.commit})",
                f"use a git clone of {pin.repository}",
            )
        ]
    else:
        at_pin = commit == pin.commit
        rows = [
            (
                f"{name}: checkout",
                at_pin,
                f"{checkout} at {commit[:12]}"
                + (" (pinned)" if at_pin else f", pinned {pin.commit[:12]}")
                + (" with local changes" if dirty else ""),
                "" if at_pin else f"git -C {checkout} checkout {pin.commit}",
            )
        ]
    if settings.launcher is None:
        return [
            *rows,
            (f"{name}: interpreter", False, problems[-1], "set python, conda_env or container"),
        ]
    launcher = f"{settings.launcher}={getattr(settings, settings.launcher)}"
    work = checkout.resolve()
    try:
        version, answer = python_version(settings.prefix(work), cwd=work, timeout=PROBE_TIMEOUT)
    except SettingsError as error:
        return [*rows, (f"{name}: interpreter", False, str(error), "fix the container template")]
    runs = version is not None
    rows.append(
        (
            f"{name}: interpreter",
            runs,
            f"{launcher}: "
            + (
                f"Python {version}"
                if runs
                else f"not a Python interpreter: asked for its version, {answer}"
            ),
            "" if runs else "check the interpreter / environment / container of this method",
        )
    )
    if runs and settings.device == "cpu":
        rows.append(_cpu_environment_check(name, settings))
    elif runs:
        code, line = _probe(settings, _GPU_PROBE)
        rows.append(
            (
                f"{name}: GPU",
                code == 0,
                line or f"exit code {code}",
                ""
                if code == 0
                else "the official code needs a CUDA GPU visible from its environment "
                "(container: --nv / --gpus all)",
            )
        )
    return rows


def cpu_pins(name: str) -> dict[str, str | None]:
    """The packages (import name -> version prefix, None: any) the doctor checks in ``name``'s CPU
    environment."""
    return METHOD_CPU_PINS.get(name, CPU_PINS)


def _cpu_environment_check(name: str, settings: CodeSettings) -> Check:
    """device=cpu: the method's stand-ins (`standins_for`) import in its environment from olatbench,
    and its packages are at `cpu_pins`."""
    import ast

    from olatbench.methods.official.cpu_standins import job_environment, standins_for

    pins = cpu_pins(name)
    standins = [
        _PROBE_IMPORTS.get(module, module)
        for module in standins_for(name)
        if module != "sitecustomize"
    ]
    code, line = _probe(
        settings,
        f"NAMES = {list(pins)!r}\nSTANDINS = {standins!r}\n" + _CPU_PROBE,
        job_environment(name),
    )
    fix = (
        "build the official CPU environment as docs/official.md says (section: running on the CPU)"
    )
    if code != 0:
        return (
            f"{name}: CPU stand-ins",
            False,
            f"the stand-ins do not import there: {line or code}",
            fix,
        )
    found = ast.literal_eval(line)
    wrong = [
        f"{module} {found[module]} (want {pin or 'any'})"
        for module, pin in pins.items()
        if str(found[module]).startswith("missing")
        or (pin and not str(found[module]).startswith(pin))
    ]
    detail = ", ".join(f"{module} {version}" for module, version in found.items())
    return (
        f"{name}: CPU stand-ins",
        not wrong,
        "stand-ins import; " + ("; ".join(wrong) if wrong else detail),
        "" if not wrong else fix,
    )


def official_checks(
    specs: Mapping[str, MethodSpec], options: Mapping[str, Mapping[str, str]] | None = None
) -> list[Check]:
    """Checks of every runnable official method that any source configures; one line when none
    is."""
    from olatbench.methods.spec import import_reference

    rows: list[Check] = []
    for name in sorted(set(options or {}) - {n for n, s in specs.items() if s.kind == "official"}):
        rows.append(
            (
                f"{name}: settings",
                False,
                "--code names no official method",
                "olatbench methods list (the *-official names)",
            )
        )
    for name, spec in sorted(specs.items()):
        if spec.kind != "official":
            continue
        code: OfficialCode = import_reference(spec.implementation)
        try:
            settings = resolve_settings(name, (options or {}).get(name))
        except SettingsError as error:
            rows.append(
                (
                    f"{name}: settings",
                    False,
                    str(error),
                    "fix olatbench.toml / --code / the variables",
                )
            )
            continue
        if settings.configured and code.runnable:
            rows.extend(check_code(spec, settings))
    if not rows:
        rows.append(
            (
                "official implementations",
                True,
                "none configured (only needed to run *-official methods)",
                "see docs/official.md",
            )
        )
    return rows
