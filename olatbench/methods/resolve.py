"""The one config resolution: a method's config from its defaults and the layers given over them,
and where each field's value came from.

Every path that makes a config goes through `resolve`: the runner's plan and dry run
(`bench.plan.resolve_config`), `Method.resolve_config` and `MethodSpec.resolve_config` (a config
from a preset string, and the runner's executor, restore and official runner rebuilding a job's
config from its job.json), `olatbench methods show` and `methods diff`. Layers, later winning (each
named by its `Source` in `ResolvedConfig.sources`):

1. ``default``: the config dataclass's own value;
2. the run length: the suite's ``iterations``, or the method's own (`MethodSpec.iterations`) when
   its spec fixes one;
3. the suite's preset (``suite preset NAME``; the method's preset named like the suite, when it has
   one), and a user suite's own ``iterations`` over it; or, for a scene of no suite with a method
   that declares a scene recipe, the preset derived from the scene (``scene recipe NAME`` for the
   recipe's values taken as they are, ``derived from the scene`` for those scaled to it:
   `olatbench.methods.scene_presets`);
4. the variant (``variant NAME``; ``a+b`` is ``a`` then ``b``, each its own source);
5. explicit values (``--set`` from the command line; ``job.json`` when a job's config is rebuilt).

Nothing here imports torch: `methods show` and `run --dry-run` resolve configs without it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from olatbench.datasets.suites import Suite
    from olatbench.methods.scene_presets import DerivedPreset

#: The variant that applies no preset (``run --variant default``; may appear in an ablation grid).
DEFAULT_VARIANT = "default"
DEFAULT_SOURCE = "default"
SET_SOURCE = "--set"


@dataclass(frozen=True)
class Layer:
    """Config values set together, and the source they are reported under
    (``"variant official"``)."""

    source: str
    values: Mapping[str, Any]


@dataclass(frozen=True)
class ResolvedConfig:
    """A resolved config and, for every one of its fields, the source of its value
    (`Layer.source`, or ``"default"``)."""

    config: Any
    sources: Mapping[str, str]

    def rows(self) -> list[tuple[str, Any, str]]:
        """(field, value, source) in the config's field order."""
        return [
            (f.name, getattr(self.config, f.name), self.sources[f.name])
            for f in fields(self.config)
        ]


def variant_presets(variant: str | None) -> list[str]:
    """The presets a variant name combines, left to right: ``"a+b"`` -> ``["a", "b"]``
    (spaces around each stripped); ``None``, ``""`` and ``"default"`` combine none. A `ValueError`
    for an empty part (``"a+"``, ``"+a"``, ``"a++b"``), which names no preset. The one parser of
    variant names."""
    if not variant or variant == DEFAULT_VARIANT:
        return []
    parts = [part.strip() for part in variant.split("+")]
    if not all(parts):
        raise ValueError(
            f"variant {variant!r} has an empty preset name: combine presets as 'a+b' (e.g. "
            "'mini+ablation-C')"
        )
    return parts


def preset_parts(
    method: str, presets: Mapping[str, Mapping[str, Any]], preset: str | None
) -> list[str]:
    """The preset names of ``preset`` (`variant_presets`), each checked against ``method``'s
    presets: a `KeyError` names an empty part or an unknown preset
    (listing ``method``'s presets)."""
    try:
        parts = variant_presets(preset)
    except ValueError as error:
        raise KeyError(f"method '{method}': {error}") from None
    for name in parts:
        if name not in presets:
            raise KeyError(
                f"method '{method}' has no preset '{name}'; known presets: "
                f"{', '.join(sorted(presets)) or 'none'} (combine with '+', e.g. 'mini+ablation-C')"
            )
    return parts


def preset_layers(
    method: str, presets: Mapping[str, Mapping[str, Any]], preset: str | None, role: str
) -> list[Layer]:
    """One layer per part of ``preset`` (``"a+b"``: ``a`` then ``b``), reported as
    ``"{role} {part}"``; none for ``None``, ``""`` and ``"default"``. A `KeyError` lists
    ``method``'s presets."""
    return [
        Layer(f"{role} {part}", presets[part]) for part in preset_parts(method, presets, preset)
    ]


def apply_layers(config_class: type, layers: Sequence[Layer]) -> ResolvedConfig:
    """``config_class(**values)`` with the layers' values merged in order (later wins), and each
    field's source."""
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for layer in layers:
        values.update(layer.values)
        sources.update(dict.fromkeys(layer.values, layer.source))
    config = config_class(**values)
    return ResolvedConfig(
        config, {f.name: sources.get(f.name, DEFAULT_SOURCE) for f in fields(config)}
    )


def suite_layers(
    presets: Mapping[str, Mapping[str, Any]],
    field_names: set[str],
    suite: Suite,
    own_iterations: int | None,
    derived: DerivedPreset | None,
) -> list[Layer]:
    """Layers 2 and 3 of the module docstring for ``suite`` (``derived`` takes the place of its
    preset)."""
    layers = []
    if "iterations" in field_names:
        length = (
            (suite.iterations, f"suite {suite.name}")
            if own_iterations is None
            else (own_iterations, "method spec")
        )
        layers.append(Layer(length[1], {"iterations": length[0]}))
    if derived is not None:
        kept = {
            name: value for name, value in derived.values.items() if name not in derived.reasons
        }
        layers += [
            Layer(f"scene recipe {derived.recipe}", kept),
            Layer(
                "derived from the scene", {name: derived.values[name] for name in derived.reasons}
            ),
        ]
    elif suite.preset in presets:
        layers.append(Layer(f"suite preset {suite.preset}", presets[suite.preset]))
        if suite.iterations_given and "iterations" in field_names:
            layers.append(Layer(f"suite {suite.name}", {"iterations": suite.iterations}))
    return layers


def resolve(
    method: str,
    config_class: type,
    presets: Mapping[str, Mapping[str, Any]],
    variant: str | None = DEFAULT_VARIANT,
    explicit: Mapping[str, Any] | None = None,
    explicit_source: str = SET_SOURCE,
    suite: Suite | None = None,
    own_iterations: int | None = None,
    derived: DerivedPreset | None = None,
) -> ResolvedConfig:
    """The config of ``method`` (module docstring): over ``config_class``'s defaults, ``suite``'s
    length and preset (or ``derived``) when a suite is given, then ``variant``'s presets, then
    ``explicit`` values (reported as ``explicit_source``). A `KeyError` names an unknown preset; the
    config class's `TypeError` / `ValueError` an unknown field or a bad value."""
    layers = (
        []
        if suite is None
        else suite_layers(
            presets, {f.name for f in fields(config_class)}, suite, own_iterations, derived
        )
    )
    layers += preset_layers(method, presets, variant, "variant")
    if explicit:
        layers.append(Layer(explicit_source, dict(explicit)))
    return apply_layers(config_class, layers)
