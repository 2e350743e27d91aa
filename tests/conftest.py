"""Shared test configuration and fixtures."""

from __future__ import annotations

import pytest


@pytest.fixture()
def no_lpips_weights(monkeypatch, tmp_path):
    """LPIPS weights made unfindable (empty caches, no packaged copy) and the warn-once state reset; the LPIPS
    caches are cleared before and after."""
    from olatbench.metrics.lpips import clear_caches

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    monkeypatch.delenv("OLATBENCH_WEIGHTS_DIR", raising=False)
    monkeypatch.setattr("olatbench.metrics.weights._package_dir", lambda name: None)
    monkeypatch.setattr("olatbench.metrics.protocols._WARNED", set())
    clear_caches()
    yield
    clear_caches()
