"""Find methods by name: the ``olatbench.methods`` entry points plus in-process registrations."""

from __future__ import annotations

from importlib.metadata import entry_points

from olatbench.methods.base import Method

ENTRY_POINT_GROUP = "olatbench.methods"
_registered: dict[str, type[Method]] = {}


def register(name: str, method_class: type[Method]) -> None:
    """Register a method class in this process (tests, notebooks); entry points need no call."""
    _registered[name] = method_class


def method_names() -> list[str]:
    """Every method name known here, sorted."""
    names = {entry.name for entry in entry_points(group=ENTRY_POINT_GROUP)}
    return sorted(names | set(_registered))


def get_method(name: str) -> type[Method]:
    """The method class registered as ``name``; a `KeyError` listing the known names otherwise."""
    if name in _registered:
        return _registered[name]
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        if entry.name == name:
            try:
                return entry.load()
            except Exception as error:  # a broken plugin must say which one, not crash with its traceback
                raise ImportError(f"method '{name}' (entry point '{entry.value}') could not be loaded: "
                                  f"{type(error).__name__}: {error}") from error
    raise KeyError(f"unknown method '{name}'; known methods: {', '.join(method_names()) or 'none'}")
