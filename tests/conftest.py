"""Shared test configuration and fixtures.

**Every test runs in its own working directory and its own cache** (`isolated_environment`,
autouse): no test reads the working directory's ``runs/`` or ``olatbench.toml`` (the README's main
job writes ``runs/`` into the checkout before its test command runs), nor the user's
``~/.cache/olatbench`` (``calibration.json``, ``file-hashes/``, ``standins/``, an installed or
damaged ``mini`` suite), nor ``$OLATBENCH_DATA``, ``$OLATBENCH_WEIGHTS_DIR`` or ``$TORCH_HOME``.
``XDG_CACHE_HOME`` points at a fresh folder per test, from the start of the session on (so modules
that look things up at collection time see the test cache too), holding three links to what the
session shares:

- ``olatbench/mini``: a folder of this session, empty at first; the first test that needs the suite
  installs it there from the package with every file's sha256 checked
  (`olatbench.datasets.synth.mini.ensure_mini_suite`, as ``olatbench datasets synth --mini`` does),
  and every later use verifies it by hash again, so a test that damages it gets it replaced, never a
  silently wrong suite;
- ``olatbench/weights``: the LPIPS weights copied into a folder of this session from where the
  user's environment finds them (``olatbench weights install``, which the README runs before the
  tests, puts them in the user's cache), each file checked against the sha256 its provenance
  records; the copy is the one read of the user's cache, made once, before any test runs. Without
  installed weights the LPIPS tests skip, as before;
- ``olatbench/ext``: the user's compiled-kernel cache itself (``$XDG_CACHE_HOME/olatbench/ext`` of
  the environment pytest started in). Shared on purpose: it is content-addressed, not user state — a
  library's folder name is a hash of its sources, headers, compiler, flags, architecture and OS
  (`olatbench._native.build`), it is written under a lock and renamed into place whole, so what a
  test loads is determined by the code under test, never by what the user did; sharing it saves
  compiling the six libraries (a minute or more) in every session. Tests of the build itself point
  ``XDG_CACHE_HOME`` at their own folder.

A test that sets ``XDG_CACHE_HOME`` itself (``monkeypatch.setenv``) overrides all of this for its
own duration.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest

SHARED_ENV_REMOVED = ("OLATBENCH_DATA", "OLATBENCH_WEIGHTS_DIR", "TORCH_HOME")
_SESSION: dict[str, object] = {}


def _user_cache() -> Path:
    """The cache of the environment pytest started in (``$XDG_CACHE_HOME`` or ``~/.cache``)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")


def _copy_verified_weights(dest: Path) -> None:
    """Copy the olatbench-format LPIPS weights the user's environment finds into ``dest``, each
    checked against the sha256 in its provenance file (a file that does not match is left out: its
    tests then skip or fail as on a machine without weights)."""
    from olatbench.metrics.weights import CHECKPOINTS, find_weights

    dest.mkdir(parents=True)
    for net in CHECKPOINTS:
        found = find_weights(net)
        if found is None or found.kind != "olatbench":
            continue
        weights = found.files[0]
        provenance = weights.with_name(f"lpips_{net}.provenance.json")
        try:
            expected = json.loads(provenance.read_text(encoding="utf-8"))["file_sha256"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if hashlib.sha256(weights.read_bytes()).hexdigest() == expected:
            shutil.copyfile(weights, dest / weights.name)
            shutil.copyfile(provenance, dest / provenance.name)


def _new_cache(root: Path) -> Path:
    """A fresh ``XDG_CACHE_HOME`` below ``root`` whose ``olatbench/{mini,weights,ext}`` link to the
    shared folders."""
    cache = Path(tempfile.mkdtemp(prefix="cache-", dir=root))
    (cache / "olatbench").mkdir()
    for name, target in _SESSION["shared"].items():
        (cache / "olatbench" / name).symlink_to(target, target_is_directory=True)
    return cache


def pytest_configure(config) -> None:
    """Make the session's shared folders and point the environment at a test cache before
    collection."""
    root = Path(tempfile.mkdtemp(prefix="olatbench-tests-"))
    ext = _user_cache() / "olatbench" / "ext"
    try:
        ext.mkdir(parents=True, exist_ok=True)
    except OSError:  # an unwritable home: the session compiles into its own folder
        ext = root / "ext"
        ext.mkdir()
    _copy_verified_weights(root / "weights")
    (root / "mini").mkdir()
    _SESSION.update(
        root=root,
        shared={"mini": root / "mini", "weights": root / "weights", "ext": ext},
        environ={name: os.environ.get(name) for name in ("XDG_CACHE_HOME", *SHARED_ENV_REMOVED)},
    )
    for name in SHARED_ENV_REMOVED:
        os.environ.pop(name, None)
    os.environ["XDG_CACHE_HOME"] = str(_new_cache(root))


def pytest_unconfigure(config) -> None:
    """Restore the environment and remove the session's folders."""
    if not _SESSION:
        return
    for name, value in _SESSION["environ"].items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value
    shutil.rmtree(_SESSION["root"], ignore_errors=True)
    _SESSION.clear()


@pytest.fixture(autouse=True)
def isolated_environment(monkeypatch, tmp_path_factory) -> Path:
    """This test's own working directory (returned) and ``XDG_CACHE_HOME`` (module docstring)."""
    cwd = tmp_path_factory.mktemp("cwd")
    monkeypatch.setenv("XDG_CACHE_HOME", str(_new_cache(_SESSION["root"])))
    for name in SHARED_ENV_REMOVED:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(cwd)
    return cwd


@pytest.fixture()
def no_lpips_weights(monkeypatch, tmp_path):
    """LPIPS weights made unfindable (empty caches, no packaged copy) and the warn-once state reset;
    the LPIPS caches are cleared before and after."""
    from olatbench.metrics.lpips import clear_caches

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    monkeypatch.delenv("OLATBENCH_WEIGHTS_DIR", raising=False)
    monkeypatch.setattr("olatbench.metrics.weights._package_dir", lambda name: None)
    monkeypatch.setattr("olatbench.metrics.protocols._WARNED", set())
    clear_caches()
    yield
    clear_caches()


@pytest.fixture()
def mitsuba_scalar_variant(monkeypatch):
    """Mitsuba's fast, deterministic ``scalar_rgb`` CPU variant for the generator's tests; the
    variant probe's cache is reset around the test."""
    from olatbench.datasets.synth import backend

    monkeypatch.setenv(backend.VARIANT_ENV, "scalar_rgb")
    backend.probe_variant.cache_clear()
    yield
    backend.probe_variant.cache_clear()
