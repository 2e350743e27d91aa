"""Every built-in method × suite × variant the planner can resolve, as JSON-ready records: the cases
of `tests/test_config_resolver.py`, which compares them with `tests/data/resolved_configs.json.gz`,
the same records written by this module (``python -m tests.config_cases OUT``) at the commit before
the one config resolver.

Each case records the fields of the resolved config that differ from its class's defaults
(`config_to_dict`) or, where the combination is refused, the error's class and message. Besides each
suite as it is (and with ``iterations=500``), a scene of no suite is covered through the derived
preset of a 64² scene of 30 images (with and without ``iterations``) and a user suite that gives its
own ``iterations``.
"""

from __future__ import annotations

import gzip
import json
import sys
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import Any

from olatbench.bench.jobs import config_to_dict
from olatbench.bench.plan import derived_preset, resolve_config
from olatbench.datasets.suites import SUITES, Suite
from olatbench.methods.registry import builtin_specs
from olatbench.methods.resolve import DEFAULT_VARIANT
from olatbench.methods.scene_presets import SceneFacts
from olatbench.methods.spec import MethodSpec

_FACTS = SceneFacts(30, 64, 64)


def variants(spec: MethodSpec) -> list[str]:
    """Default, every preset alone, and every combination an ablation grid names."""
    names = [DEFAULT_VARIANT, *spec.presets]
    for grid in spec.ablations.values():
        names += grid
    return list(dict.fromkeys(names))


def _json(value: Any) -> Any:
    return json.loads(json.dumps(value))


def _outcome(resolve: Callable[[], Any], defaults: dict[str, Any]) -> dict[str, Any]:
    """The resolved config's fields that differ from ``defaults`` (its class's), or the refusal."""
    try:
        config = _json(config_to_dict(resolve()))
    except Exception as error:  # the refusal is part of what must not change
        return {"error": f"{type(error).__name__}: {error}"}
    return {
        "config": {
            key: value for key, value in config.items() if defaults.get(key, object()) != value
        }
    }


def _with_derived(spec: MethodSpec, suite: Suite, variant: str, overrides: dict[str, Any]) -> Any:
    derived = derived_preset(spec, suite, _FACTS, overrides)
    return resolve_config(spec, suite, variant, overrides=overrides, derived=derived)


def cases() -> dict[str, dict[str, Any]]:
    """``{"method|suite|variant|extra": outcome}`` for every case (module docstring)."""
    out: dict[str, dict[str, Any]] = {}
    for name, spec in sorted(builtin_specs().items()):
        defaults = _json(config_to_dict(spec.load_config_class()()))
        out[f"{name}|defaults"] = {"config": defaults}
        for suite_name, suite in SUITES.items():
            user = replace(
                suite,
                name=f"own-{suite_name}",
                scene_paths={"scene": "/nowhere"},
                method_preset=suite_name,
            )
            given = replace(user, iterations=1234, iterations_given=True)
            for variant in variants(spec):
                key = f"{name}|{suite_name}|{variant}"
                out[key] = _outcome(partial(resolve_config, spec, suite, variant), defaults)
                out[f"{key}|iterations=500"] = _outcome(
                    partial(resolve_config, spec, suite, variant, overrides={"iterations": 500}),
                    defaults,
                )
                out[f"{key}|derived"] = _outcome(
                    partial(_with_derived, spec, user, variant, {}), defaults
                )
                out[f"{key}|derived|iterations=700"] = _outcome(
                    partial(_with_derived, spec, user, variant, {"iterations": 700}), defaults
                )
                out[f"{key}|suite-iterations"] = _outcome(
                    partial(_with_derived, spec, given, variant, {}), defaults
                )
        for variant in variants(spec):
            out[f"{name}|spec.resolve_config|{variant}"] = _outcome(
                partial(spec.resolve_config, variant), defaults
            )
    return out


def write(path: str) -> None:
    """``cases()`` as gzipped JSON, one case a line (no time stamp: the same cases give the same
    bytes)."""
    lines = [
        f"{json.dumps(key)}: {json.dumps(value, sort_keys=True)}"
        for key, value in sorted(cases().items())
    ]
    with open(path, "wb") as file:
        file.write(gzip.compress(("{\n" + ",\n".join(lines) + "\n}\n").encode(), mtime=0))


def read(path: str) -> dict[str, dict[str, Any]]:
    """What `write` wrote."""
    with gzip.open(path, "rt") as file:
        return json.load(file)


if __name__ == "__main__":
    write(sys.argv[1])
