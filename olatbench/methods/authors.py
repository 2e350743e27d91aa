"""The authors' configuration of a native method, as data: each config field's counterpart in the
authors' code (value and file:line at the pinned commit), and why a preset departs from it.

A method that reimplements published code declares an `AuthorsConfig` (`MethodSpec.authors`) beside
its presets. From it come the variant ``official`` (`AuthorsConfig.preset`: every field with a
counterpart takes the authors' value, except the run settings the suite decides for both runners:
length, budget, initialisation, density window, background, refinement, which the official runner
passes the same on that suite) and `olatbench methods diff` (`departures`: each field of a resolved
config that departs from the authors', with the authors' value, where it is, and the reason and
measured effect recorded for the preset the value came from).

Iteration-valued fields are compared at the config's ``reference_iterations``: a run scales the
native value and the official runner the authors' flag by the same rule
(`olatbench.methods.run_length.scaled_steps`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Any

from olatbench.methods.resolve import DEFAULT_SOURCE, ResolvedConfig

#: The variant every spec with an `AuthorsConfig` gets: the authors' values over the suite's run
#: settings.
OFFICIAL_VARIANT = "official"
#: Fields the official runner passes from the suite exactly as the native suite preset sets them,
#: for every official code (`olatbench.methods.official.specs`): run length, initial points,
#: Gaussian budget and density window. A spec's `AuthorsConfig.suite_fields` adds its own.
RUNNER_SUITE_FIELDS = frozenset(
    {
        "iterations",
        "reference_iterations",
        "num_init_gaussians",
        "init_shape",
        "init_radius",
        "max_gaussians",
        "position_lr_max_steps",
        "densify_from",
        "densify_until",
        "opacity_reset_interval",
    }
)
#: The source prefixes whose remainder names a preset (`olatbench.methods.resolve`).
_PRESET_SOURCES = ("suite preset ", "variant ", "scene recipe ")


@dataclass(frozen=True)
class AuthorsValue:
    """A field's value in the authors' code and where it is set (``"arguments/__init__.py:69"``, at
    the pinned commit); ``note`` says how the code's setting maps to the field when that is not one
    to one."""

    value: Any
    where: str
    note: str = ""


@dataclass(frozen=True)
class Departure:
    """Why a preset (or the config's default) departs from the authors' value of a field, and what
    the departure was measured to do (or that it was not measured), with where the measurement is
    written up."""

    reason: str
    effect: str


@dataclass(frozen=True)
class Unswitchable:
    """A difference from the authors' code that no config field switches: what, where in their code,
    and ours."""

    what: str
    where: str
    native: str


@dataclass(frozen=True)
class AuthorsConfig:
    """The authors' configuration of one method (module docstring). ``values``: field ->
    `AuthorsValue` for every config field with a counterpart; ``suite_fields``: those the suite
    decides for both runners (not in `preset`, not reported as departures); ``departures``: source
    (``"default"`` or a preset name) -> field -> `Departure`; ``unswitchable``: differences no field
    switches."""

    repository: str
    commit: str
    values: Mapping[str, AuthorsValue]
    suite_fields: frozenset[str]
    departures: Mapping[str, Mapping[str, Departure]] = field(default_factory=dict)
    unswitchable: tuple[Unswitchable, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", MappingProxyType(dict(self.values)))
        object.__setattr__(
            self,
            "departures",
            MappingProxyType({k: MappingProxyType(dict(v)) for k, v in self.departures.items()}),
        )

    def preset(self) -> dict[str, Any]:
        """The variant ``official``: the authors' value of every field but the suite's."""
        return {
            name: entry.value
            for name, entry in self.values.items()
            if name not in self.suite_fields
        }

    def check(self, config_class: type, method: str) -> None:
        """A `ValueError` naming the fields of ``values``, ``suite_fields`` or ``departures`` that
        ``config_class`` lacks (a renamed field must not leave a stale row)."""
        names = {f.name for f in fields(config_class)}
        listed = (
            set(self.values)
            | set(self.suite_fields)
            | {f for notes in self.departures.values() for f in notes}
        )
        unknown = sorted(listed - names)
        if unknown:
            raise ValueError(
                f"method '{method}': its authors' configuration names fields its config lacks: "
                f"{', '.join(unknown)}"
            )


@dataclass(frozen=True)
class DepartureRow:
    """One field where a resolved config departs from the authors': its value and source, the
    authors' value and where it is set, and the recorded `Departure` (None: none recorded for that
    source)."""

    name: str
    value: Any
    source: str
    authors: AuthorsValue
    departure: Departure | None


def source_preset(source: str) -> str:
    """The preset (or ``"default"``) a `ResolvedConfig` source names; other sources
    (``--set``, a suite's length) as they are."""
    for prefix in _PRESET_SOURCES:
        if source.startswith(prefix):
            return source[len(prefix) :]
    return source if source != DEFAULT_SOURCE else "default"


def departures(resolved: ResolvedConfig, authors: AuthorsConfig) -> list[DepartureRow]:
    """The fields of ``resolved`` (not the suite's) whose value differs from the authors', in the
    config's order, each with the `Departure` recorded for the preset its value came from."""
    rows = []
    for name, value, source in resolved.rows():
        entry = authors.values.get(name)
        if entry is None or name in authors.suite_fields or _same(value, entry.value):
            continue
        recorded = authors.departures.get(source_preset(source), {}).get(name)
        rows.append(DepartureRow(name, value, source, entry, recorded))
    return rows


def _same(value: Any, authors: Any) -> bool:
    """Equal as config values: lists and tuples alike, a bool never equal to a number."""
    if isinstance(value, (list, tuple)) and isinstance(authors, (list, tuple)):
        return list(value) == list(authors)
    return isinstance(value, bool) == isinstance(authors, bool) and bool(value == authors)
