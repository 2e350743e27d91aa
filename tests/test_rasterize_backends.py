"""Rasterizer backend selection: auto, environment override, the fallback warning when the C++ build
fails, the build variants and the cache (the build machinery itself: tests/test_native.py)."""

from __future__ import annotations

import warnings

import pytest
import torch
from test_rasterize_scenes import camera, scene

import olatbench.gaussians.backends as backends
from olatbench import _native
from olatbench._native import build
from olatbench.gaussians.backends import cpu_backend_status, resolve_backend
from olatbench.gaussians.backends.cpu import LIBRARY
from olatbench.gaussians.render import render


@pytest.fixture
def fresh_build(monkeypatch, tmp_path):
    """An empty build cache and no remembered build outcome; restored afterwards."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("OLATBENCH_RASTERIZER", raising=False)
    LIBRARY.reset()
    _native.reset_fallback_warnings()
    yield tmp_path
    LIBRARY.reset()
    _native.reset_fallback_warnings()


def tiny_render(backend="auto"):
    W, H = 17, 13
    w2c, K = camera(W, H, dtype=torch.float32)
    s = {k: v.float() for k, v in scene(5).items()}
    return render(s["means"], s["quats"], s["scales"], s["opacities"], s["features"], w2c, K, W, H,
                  s["background"], backend=backend)  # fmt: skip


def test_broken_compiler_falls_back_to_torch_with_one_warning(fresh_build, monkeypatch):
    monkeypatch.setenv("OLATBENCH_CXX", str(fresh_build / "no-such-compiler"))
    ok, detail = cpu_backend_status()
    assert not ok and "no-such-compiler" in detail
    with pytest.warns(
        RuntimeWarning,
        match="rasterizer backend 'cpu' is unavailable, falling back.*no-such-compiler",
    ):
        assert resolve_backend("auto", "cpu") == "torch"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert resolve_backend("auto", "cpu") == "torch"  # only one warning per process
        out = tiny_render()
    assert out["image"].shape == (13, 17, 3)
    with pytest.raises(RuntimeError, match="no-such-compiler"):
        tiny_render(backend="cpu")  # an explicit request fails loudly instead of falling back


def test_unwritable_cache_is_a_clear_build_error(fresh_build, monkeypatch):
    blocker = fresh_build / "file-not-folder"
    blocker.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    ok, detail = cpu_backend_status()
    assert not ok and "XDG_CACHE_HOME" in detail


def test_failing_compilation_reports_the_compiler_output(fresh_build, monkeypatch):
    monkeypatch.setenv("OLATBENCH_CXX", "g++ -DOLATBENCH_NO_SUCH_FLAG -fno-such-option")
    ok, detail = cpu_backend_status()
    assert not ok and "-fno-such-option" in detail and "failed" in detail


def test_single_threaded_build_when_openmp_is_missing(fresh_build, monkeypatch):
    fake = fresh_build / "cxx-without-openmp"
    fake.write_text(
        '#!/bin/sh\nfor a in "$@"; do [ "$a" = -fopenmp ] && { echo "no OpenMP here" >&2; exit 1; '
        '}; done\nexec g++ "$@"\n'
    )
    fake.chmod(0o755)
    monkeypatch.setenv("OLATBENCH_CXX", str(fake))
    with pytest.warns(
        RuntimeWarning, match="(?s)olatbench_gaussians is a single-threaded build.*no OpenMP here"
    ):
        ok, detail = cpu_backend_status()  # slower than it could be: said once, like a fallback
    assert ok and "single-threaded" in detail and "no OpenMP here" in detail
    assert LIBRARY.load().path == LIBRARY.path("serial")
    out = tiny_render(backend="cpu")
    assert float(out["alpha"].max()) > 0


def test_fresh_build_lands_in_the_hashed_cache(fresh_build):
    ok, detail = cpu_backend_status()
    assert ok, detail
    path = LIBRARY.path()
    assert path.exists() and str(path) == detail
    assert path.parent.parent == fresh_build / "olatbench" / "ext"
    assert (
        path.parent.name == f"olatbench_gaussians-{build.build_key(LIBRARY.name, LIBRARY.sources)}"
    )
    assert not list(path.parent.glob(".build-*"))  # the temporary file was renamed into place
    assert resolve_backend("auto", "cpu") == "cpu"


def test_environment_overrides_auto(monkeypatch):
    monkeypatch.setenv("OLATBENCH_RASTERIZER", "torch")
    assert resolve_backend("auto", "cpu") == "torch"
    assert tiny_render()["image"].dtype == torch.float32
    monkeypatch.setenv("OLATBENCH_RASTERIZER", "banana")
    with pytest.raises(ValueError, match="OLATBENCH_RASTERIZER"):
        resolve_backend("auto", "cpu")
    monkeypatch.setenv("OLATBENCH_RASTERIZER", "cpu")
    assert resolve_backend("torch", "cpu") == "torch"  # explicit requests win over the variable
    if cpu_backend_status()[0]:
        assert resolve_backend("auto", "cpu") == "cpu"


def test_cuda_selection_logic(monkeypatch):
    monkeypatch.delenv("OLATBENCH_RASTERIZER", raising=False)
    monkeypatch.setattr(backends, "gsplat_available", lambda: True)
    assert resolve_backend("auto", "cuda") == "cuda"
    assert resolve_backend("cuda", "cuda") == "cuda"
    monkeypatch.setattr(backends, "gsplat_available", lambda: False)
    _native.reset_fallback_warnings()
    with pytest.warns(
        RuntimeWarning, match="backend 'cuda' is unavailable, falling back to 'torch'.*gsplat"
    ):
        assert resolve_backend("auto", "cuda") == "torch"  # never a silent fallback
    _native.reset_fallback_warnings()
    with pytest.raises(RuntimeError, match="gsplat"):
        resolve_backend("cuda", "cuda")
    with pytest.raises(ValueError, match="CUDA tensors"):
        resolve_backend("cuda", "cpu")
    with pytest.raises(ValueError, match="CPU tensors"):
        resolve_backend("cpu", "cuda")
    with pytest.raises(ValueError, match="unknown"):
        resolve_backend("vulkan", "cpu")


def test_unsupported_dtype_uses_torch(monkeypatch):
    monkeypatch.delenv("OLATBENCH_RASTERIZER", raising=False)
    assert resolve_backend("auto", "cpu", torch.bfloat16) == "torch"
