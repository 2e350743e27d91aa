"""``choose_backend``: the one rule by which every kernel with several implementations picks one.

A resolver (rasterizer, projection, binning, light pass, SSIM loss, SSD-GS shading) names its
backends in order of preference, the reference last, each with a check saying why it cannot run
these inputs (or None when it can). A backend named after a device type (``"cpu"``, ``"cuda"``) runs
only on tensors of that device; any other (``"torch"``) runs anywhere. Two kinds of "cannot":

- the inputs do not suit it (another dtype or device, an option it does not implement): ``"auto"``
  passes over it silently, as documented by each resolver;
- it is *missing* (its C++ library did not build, its package is not installed): ``"auto"`` falls
  back to the next backend with one ``RuntimeWarning`` per resolver and backend per process, saying
  why and how to fix it; ``olatbench doctor`` shows the same reason. A fallback is never silent.

An explicitly requested backend is used as asked or fails: ``ValueError`` when the inputs do not
suit it, ``RuntimeError`` when it is missing. Torch-free: devices are given by their type name.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass

DEVICE_BACKENDS = ("cpu", "cuda")  # backends that run only on the device type of their name


@dataclass(frozen=True)
class Unavailable:
    """Why a backend cannot run: ``reason`` (a clause, e.g. "it supports float32 and float64, not
    bfloat16"); ``missing``: it is not built or installed, rather than unsuited to these inputs."""

    reason: str
    missing: bool = False


Check = Callable[[], "Unavailable | None"]

_warned: set[tuple[str, str]] = set()


def always() -> None:
    """The check of a backend that runs any input (the reference)."""
    return None


def choose_backend(
    requested: str,
    device: str,
    available: Mapping[str, Check],
    *,
    kind: str,
    env_var: str | None = None,
) -> str:
    """The backend to use: one of ``available``'s names.

    ``requested``: ``"auto"`` or a name of ``available``. ``device``: the tensors' device type
    ("cpu", "cuda", ...). ``available``: backend name -> check, in ``"auto"``'s order of preference,
    a backend that always runs last. ``kind`` names the resolver in messages ("rasterizer", "SSIM").
    ``env_var``: when set and ``requested`` is ``"auto"``, its value (if not empty) replaces the
    request, e.g. OLATBENCH_RASTERIZER=torch. Checks run lazily, in order, and only for backends
    that suit ``device``."""
    name, origin = requested, ""
    if requested == "auto" and env_var:
        value = os.environ.get(env_var, "").strip().lower()
        if value:
            name, origin = value, f" (from the environment variable {env_var}={value!r})"
    if name != "auto" and name not in available:
        raise ValueError(
            f"unknown {kind} backend {name!r}{origin}; choose one of {', '.join(available)} or "
            "'auto'"
        )
    if name != "auto":
        problem = _problem(name, device, available[name])
        if problem is None:
            return name
        if problem.missing:
            raise RuntimeError(f"{kind} backend {name!r}{origin} is unavailable: {problem.reason}")
        others = " or ".join(repr(other) for other in ("auto", *available) if other != name)
        raise ValueError(
            f"{kind} backend {name!r}{origin} cannot run these inputs: {problem.reason}; use "
            f"{others}"
        )
    passed_over: list[tuple[str, Unavailable]] = []
    for candidate, check in available.items():
        problem = _problem(candidate, device, check)
        if problem is None:
            for missing_name, missing in passed_over:
                _warn_once(kind, missing_name, candidate, missing.reason, env_var)
            return candidate
        if problem.missing:
            passed_over.append((candidate, problem))
    reasons = "; ".join(f"{candidate}: {problem.reason}" for candidate, problem in passed_over)
    raise RuntimeError(
        f"no {kind} backend can run on {device}" + (f" ({reasons})" if reasons else "")
    )


def _problem(name: str, device: str, check: Check) -> Unavailable | None:
    if name in DEVICE_BACKENDS and device != name:
        return Unavailable(f"it needs {name.upper()} tensors, got {device}")
    return check()


def _warn_once(kind: str, name: str, chosen: str, reason: str, env_var: str | None) -> None:
    if (kind, name) in _warned:
        return
    _warned.add((kind, name))
    silence = f"\nSet {env_var}={chosen} to silence this warning." if env_var else ""
    warnings.warn(
        f"olatbench: the {kind} backend {name!r} is unavailable, falling back to {chosen!r}. "
        f"Reason: {reason}{silence}",
        RuntimeWarning,
        stacklevel=4,
    )


def reset_fallback_warnings() -> None:
    """Allow the fallback warnings to be shown again (for tests)."""
    _warned.clear()


__all__ = ["Check", "Unavailable", "always", "choose_backend", "reset_fallback_warnings"]
