"""Find methods by name, as `MethodSpec`s, without importing their implementations (no torch).

Three sources, later ones winning on a name clash except where noted:

1. the built-in catalogue `BUILTIN_SPECS` (``"module:attribute"`` references to a `MethodSpec` or a
   sequence of them, in torch-free modules);
2. the ``olatbench.methods`` entry points (plugins), pointing at a `MethodSpec` or, old style, at a
   `Method` class (imported to describe it). An entry point named like a built-in spec is ignored:
   the built-in wins (a stale installation's metadata may still list the built-ins' old class entry
   points);
3. in-process registrations (`register`, for tests and notebooks), which win over both.
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib.metadata import entry_points
from typing import TYPE_CHECKING

from olatbench.methods.spec import DEFAULT_EVALUATION, MethodSpec, import_reference
from olatbench.names import did_you_mean, match_name

if TYPE_CHECKING:
    from olatbench.methods.base import Method

ENTRY_POINT_GROUP = "olatbench.methods"

#: The built-in methods' specs (official implementations add theirs here).
BUILTIN_SPECS: tuple[str, ...] = (
    "olatbench.methods.ssdgs.spec:SPEC",
    "olatbench.methods.baselines.gs3dgs_spec:SPEC",
    "olatbench.methods.baselines.gs3_spec:SPEC",
    "olatbench.methods.official.specs:SPECS",
)

_registered: dict[str, MethodSpec] = {}
_registered_classes: dict[str, type[Method]] = {}


def spec_from_class(name: str, method_class: type[Method], kind: str = "plugin") -> MethodSpec:
    """A spec describing an old-style method class (its presets, ablation grids, description,
    capabilities and evaluation protocol)."""
    config_class = method_class.config_class
    return MethodSpec(
        name=name,
        description=(method_class.description or "").strip(),
        implementation=_reference(method_class),
        config=_reference(config_class),
        kind=kind,  # type: ignore[arg-type]
        presets=dict(method_class.presets),
        ablations=dict(getattr(method_class, "ablations", {})),
        iterations=getattr(method_class, "training_iterations", None),
        capabilities=frozenset(getattr(method_class, "capabilities", frozenset())),
        evaluation=getattr(method_class, "evaluation", DEFAULT_EVALUATION),
    )


def register(name: str | MethodSpec, method_class: type[Method] | None = None) -> None:
    """Register a method in this process: ``register(spec)`` or ``register(name, MethodClass)``."""
    if isinstance(name, MethodSpec):
        if method_class is not None:
            raise TypeError("register(spec) takes no class: the spec names its implementation")
        _registered[name.name] = name
        _registered_classes.pop(name.name, None)
        return
    if method_class is None:
        raise TypeError("register(name, method_class) needs the class (or pass a MethodSpec)")
    _registered[name] = spec_from_class(name, method_class)
    _registered_classes[name] = method_class


def _as_specs(value: object, reference: str) -> list[MethodSpec]:
    if isinstance(value, MethodSpec):
        return [value]
    if (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and all(isinstance(v, MethodSpec) for v in value)
    ):
        return list(value)
    raise TypeError(f"{reference} is neither a MethodSpec nor a sequence of them")


def builtin_specs() -> dict[str, MethodSpec]:
    """The catalogue's specs by name (imports only the torch-free spec modules)."""
    specs: dict[str, MethodSpec] = {}
    for reference in BUILTIN_SPECS:
        for spec in _as_specs(import_reference(reference), reference):
            if spec.name in specs:
                raise ValueError(f"two built-in method specs are named '{spec.name}' ({reference})")
            specs[spec.name] = spec
    return specs


def _plugin_entries(builtin: set[str]) -> dict[str, object]:
    return {
        entry.name: entry
        for entry in entry_points(group=ENTRY_POINT_GROUP)
        if entry.name not in builtin
    }


def method_names() -> list[str]:
    """Every method name known here, sorted (imports no plugin)."""
    builtin = set(builtin_specs())
    return sorted(builtin | set(_plugin_entries(builtin)) | set(_registered))


def canonical_method_name(name: str) -> str:
    """The known method ``name`` names (exactly, or ignoring case when only one matches:
    `olatbench.names`); a `KeyError` with a "did you mean" and the known names otherwise."""
    known = method_names()
    matched = match_name(name, known)
    if matched is None:
        raise KeyError(
            f"unknown method '{name}'{did_you_mean(name, known)}; known methods: "
            f"{', '.join(known) or 'none'}"
        )
    return matched


def get_spec(name: str) -> MethodSpec:
    """The spec of method ``name``; a `KeyError` listing the known names, or an `ImportError` naming
    the entry point of a plugin that cannot be loaded. Names match ignoring case where that is
    unambiguous (``SSDGS``)."""
    builtin = builtin_specs()
    if name not in _registered and name not in builtin:
        name = canonical_method_name(name)
    if name in _registered:
        return _registered[name]
    if name in builtin:
        return builtin[name]
    entry = _plugin_entries(set(builtin))[name]
    try:
        target = entry.load()  # type: ignore[attr-defined]
    except Exception as error:  # a broken plugin must say which one, not crash with its traceback
        raise ImportError(
            f"method '{name}' (entry point '{entry.value}') could not be loaded: "  # type: ignore[attr-defined]
            f"{type(error).__name__}: {error}"
        ) from error
    if isinstance(target, MethodSpec):
        if target.name != name:
            raise ImportError(f"entry point '{name}' points at the spec of method '{target.name}'")
        return target
    if isinstance(target, type):
        _registered_classes.setdefault(name, target)
        return spec_from_class(name, target)
    raise ImportError(
        f"method '{name}' (entry point '{entry.value}') is neither a MethodSpec nor a Method class"
    )  # type: ignore[attr-defined]


def get_method(name: str) -> type[Method]:
    """The implementation class of method ``name`` (imports it: usually torch)."""
    spec = get_spec(name)
    if name in _registered_classes:
        return _registered_classes[name]
    try:
        return spec.load_implementation()
    except Exception as error:
        raise ImportError(
            f"method '{name}': its implementation {spec.implementation} could not be imported: "
            f"{type(error).__name__}: {error}"
        ) from error


def config_class(spec: MethodSpec) -> type:
    """The config dataclass of ``spec`` (a class registered in-process gives its own, importable or
    not)."""
    registered = _registered_classes.get(spec.name)
    if registered is not None and spec.implementation == _reference(registered):
        return registered.config_class
    return spec.load_config_class()


def _reference(target: type) -> str:
    return f"{target.__module__}:{target.__qualname__}"
