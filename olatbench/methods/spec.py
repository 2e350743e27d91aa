"""Method specs: what the runner, `olatbench methods` and the reports know of a method without
importing it.

A spec is plain data (stdlib only, never torch): the method's name and one-line description, where
its implementation lives (a ``"module:Class"`` string imported only to train or render), its config
dataclass (``"module:Class"`` in a torch-free module, so `methods show` and `run --dry-run` can
resolve configs), its presets per suite and named variants, the ablation grids it offers, the
outputs it renders and what it can do.

Official implementations (the authors' code run in its own environment) are specs too:
``kind="official"`` with a `SourcePin` saying which repository and commit the spec was written
against and what was verified.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

from olatbench.methods.resolve import (
    DEFAULT_VARIANT,
    SET_SOURCE,
    ResolvedConfig,
    resolve,
    variant_presets,
)
from olatbench.names import path_component

#: The evaluation protocol of a spec that names none: the test views scored as given
#: (`olatbench.methods.evaluation_protocol`).
DEFAULT_EVALUATION = "olatbench.methods.evaluation_protocol:EvaluationProtocol"

MethodKind = Literal["native", "official", "plugin"]
SourceStatus = Literal["verified", "unverified", "no public code"]

#: Capabilities a spec may declare (the runner and tools check these, never method names).
CAPABILITIES = frozenset(
    {
        "relight",  # renders under a new point light
        "refine_view",  # its evaluation protocol refines test views' poses/lights at test time
        "components",  # renders named components beside rgb (see MethodSpec.outputs)
        "checkpoint",  # state_dict / load_state_dict: resumable in-process training
        # starts its Gaussians at Views.points (a scene's points3d.ply, run --init-points)
        "init_points",
    }
)


@dataclass(frozen=True)
class SourcePin:
    """Where an official implementation's code comes from and how far olatbench has checked it.

    ``commit`` is 40 lowercase hex digits, or ``"unverified"`` when it could not be checked from
    here; ``verified`` says in one or two sentences what was verified and how (read, run on a GPU,
    compared, ...).
    """

    repository: str  # "owner/name" on GitHub
    commit: str
    status: SourceStatus
    verified: str = ""


@dataclass(frozen=True)
class AblationGrid(Sequence[str]):
    """One ablation grid (``run --ablation NAME``): its ``variants`` (preset names, ``"a+b"``
    combinations or ``"default"``) and its ``reference``, the variant every other one is compared
    with (the full model; one of the variants). The reports read the reference from each job's
    job.json (``Job.ablation``), never from a name. A grid given as a plain sequence (a class
    registered without a spec) has no reference."""

    variants: tuple[str, ...]
    reference: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "variants", tuple(self.variants))
        if self.reference is not None and self.reference not in self.variants:
            raise ValueError(
                f"ablation grid {self.variants}: its reference {self.reference!r} is not one of "
                "them"
            )

    def __getitem__(self, index):  # type: ignore[override]
        return self.variants[index]

    def __len__(self) -> int:
        return len(self.variants)

    def __iter__(self) -> Iterator[str]:
        return iter(self.variants)


def _grid(variants: AblationGrid | Sequence[str]) -> AblationGrid:
    return variants if isinstance(variants, AblationGrid) else AblationGrid(tuple(variants))


def _frozen(mapping: Mapping[str, Any] | None) -> Mapping[str, Any]:
    return MappingProxyType(dict(mapping or {}))


@dataclass(frozen=True)
class MethodSpec:
    """One method as data. ``presets`` maps a preset name to config overrides: a preset named like a
    suite (``"nrhints"``) is applied to every job on that suite, the others are variants chosen with
    ``--variant`` (``"a+b"`` applies ``a`` then ``b``). ``ablations`` maps a grid name
    (``"components"``) to its variants and reference variant (`AblationGrid`). ``iterations``
    replaces the suite's training length with the method's own (None: the suite's); 0 declares a
    learning-free method: ``setup`` does all the work and no training step runs, whatever the suite
    says. ``scene_recipe`` names the preset a scene of no suite gets scaled to it
    (`olatbench.methods.scene_presets`). ``evaluation`` (``"module:Class"``) is the method's
    evaluation protocol: how its test views are posed before they are scored
    (`olatbench.methods.evaluation_protocol`; the default scores them as given)."""

    name: str
    description: str
    implementation: str  # "module:Class" of the Method subclass
    config: str  # "module:Class" of the config dataclass (torch-free module)
    kind: MethodKind = "native"
    presets: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    # plain sequences are read as grids
    ablations: Mapping[str, AblationGrid] = field(default_factory=dict)
    outputs: tuple[str, ...] = ("rgb",)
    capabilities: frozenset[str] = frozenset()
    source: SourcePin | None = None  # official implementations only
    # training steps the method always takes (None: the suite's; 0: learning-free)
    iterations: int | None = None
    # the preset scaled to scenes of no suite (olatbench.methods.scene_presets; None: they get their
    # format's preset)
    scene_recipe: str | None = None
    evaluation: str = DEFAULT_EVALUATION
    # "module:ATTRIBUTE" of the method's `AuthorsConfig` (olatbench.methods.authors: the authors'
    # values, the variant "official", `olatbench methods diff`), in a torch-free module; None: the
    # method has no authors' code
    authors: str | None = None

    def __post_init__(self) -> None:
        path_component(self.name, "method")  # it names a folder of each of its jobs
        if self.iterations is not None and (
            isinstance(self.iterations, bool)
            or not isinstance(self.iterations, int)
            or self.iterations < 0
        ):
            raise ValueError(
                f"method spec {self.name!r}: iterations must be a whole number >= 0 or None, not "
                f"{self.iterations!r}"
            )
        for reference in (
            self.implementation,
            self.config,
            self.evaluation,
            *((self.authors,) if self.authors else ()),
        ):
            module, sep, attribute = reference.partition(":")
            if not (module and sep and attribute):
                raise ValueError(
                    f"method spec {self.name!r}: {reference!r} is not of the form 'module:Class'"
                )
        unknown = sorted(set(self.capabilities) - CAPABILITIES)
        if unknown:
            raise ValueError(
                f"method spec {self.name!r}: unknown capabilities {unknown}; known: "
                f"{sorted(CAPABILITIES)}"
            )
        if self.scene_recipe is not None and self.scene_recipe not in self.presets:
            raise ValueError(
                f"method spec {self.name!r}: scene_recipe names no preset ({self.scene_recipe!r})"
            )
        if (self.kind == "official") != (self.source is not None):
            raise ValueError(
                f"method spec {self.name!r}: official methods, and only they, carry a source pin"
            )
        for grid, variants in self.ablations.items():
            missing = sorted(
                {
                    part
                    for variant in variants
                    for part in variant_presets(variant)
                    if part not in self.presets
                }
            )
            if missing:
                raise ValueError(
                    f"method spec {self.name!r}: ablation grid {grid!r} names unknown presets "
                    f"{missing}"
                )
        object.__setattr__(
            self, "presets", _frozen({k: _frozen(v) for k, v in self.presets.items()})
        )
        object.__setattr__(
            self, "ablations", _frozen({k: _grid(v) for k, v in self.ablations.items()})
        )
        object.__setattr__(self, "capabilities", frozenset(self.capabilities))

    def ablation_of(self, variant: str, grid: str | None = None) -> dict[str, str] | None:
        """``{"grid", "reference"}`` of the ablation grid a job of ``variant`` belongs to, for its
        job.json: the grid ``grid`` (``run --ablation``) when it lists the variant, else the first
        grid that lists it; None when none does, when that grid names no reference, and for
        ``default`` unless ``grid`` lists it (a plain run is no ablation). ``variant`` may carry a
        label's ``~overrides`` suffix (`olatbench.bench.plan.variant_label`)."""
        name = variant.split("~")[0]
        if grid is not None and name in self.ablations.get(grid, ()):
            chosen: str | None = grid
        elif name == DEFAULT_VARIANT:
            return None
        else:
            chosen = next(
                (g for g, grid_variants in self.ablations.items() if name in grid_variants), None
            )
        if chosen is None or self.ablations[chosen].reference is None:
            return None
        return {"grid": chosen, "reference": self.ablations[chosen].reference}

    def resolve_config(self, preset: str | None = None, **overrides: Any) -> Any:
        """The config dataclass with the presets named in ``preset`` (``"a+b"``, left to right),
        then ``overrides``, applied over its defaults (`olatbench.methods.resolve`; imports only the
        torch-free config module)."""
        return self.resolve_sources(preset, overrides).config

    def resolve_sources(
        self,
        preset: str | None = None,
        overrides: Mapping[str, Any] | None = None,
        overrides_source: str = SET_SOURCE,
    ) -> ResolvedConfig:
        """`resolve_config` with the source of each field's value."""
        return resolve(
            self.name, self.load_config_class(), self.presets, preset, overrides, overrides_source
        )

    def load_authors(self) -> Any:
        """The method's `AuthorsConfig` (None when it declares none), checked against its config
        class."""
        if self.authors is None:
            return None
        authors = import_reference(self.authors)
        authors.check(self.load_config_class(), self.name)
        return authors

    def load_config_class(self) -> type:
        """The config dataclass (imports only its torch-free module)."""
        return import_reference(self.config)

    def load_implementation(self) -> type:
        """The `Method` subclass (imports the implementation, usually torch)."""
        return import_reference(self.implementation)


def import_reference(reference: str) -> Any:
    """Import ``"package.module:Qual.Name"`` and return the attribute."""
    module_name, _, qualname = reference.partition(":")
    target: Any = importlib.import_module(module_name)
    for part in qualname.split("."):
        target = getattr(target, part)
    return target
