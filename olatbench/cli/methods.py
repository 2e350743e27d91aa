"""``olatbench methods list``, ``methods show NAME`` and ``methods diff NAME``: read from the method
specs (no torch)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import click

from olatbench.cli.options import json_option


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def methods() -> None:
    """List the installed methods and show their presets and config fields.

    \b
    Examples:
      olatbench methods list
      olatbench methods show ssdgs
      olatbench methods diff ssdgs --variant mini
    """


def _spec(name: str):
    from olatbench.methods.registry import get_spec

    try:
        return get_spec(name)
    except KeyError as error:
        raise click.UsageError(f"{error.args[0]}. See: olatbench methods list") from None
    except ImportError as error:
        raise click.ClickException(f"method '{name}' cannot be loaded: {error}") from None


def _kind(spec) -> str:
    return f"{spec.kind}, {spec.source.status}" if spec.source is not None else spec.kind


def _official_code(spec):
    """The `OfficialCode` of an official method (a torch-free import), or None."""
    if spec.kind != "official":
        return None
    from olatbench.methods.spec import import_reference

    return import_reference(spec.implementation)


def _method_json(name: str) -> dict:
    """One method as data (``available: false`` with the reason when its spec cannot be loaded)."""
    try:
        spec = _spec(name)
    except click.ClickException as error:
        return {"name": name, "available": False, "error": error.message}
    return {
        "name": name,
        "available": True,
        "kind": spec.kind,
        "status": spec.source.status if spec.source is not None else None,
        "description": spec.description.strip(),
        "implementation": spec.implementation,
        "presets": list(spec.presets),
        "ablations": {grid: list(v) for grid, v in spec.ablations.items()},
        "outputs": list(spec.outputs),
        "capabilities": sorted(spec.capabilities),
        "iterations": spec.iterations,
        "source": None
        if spec.source is None
        else {"repository": spec.source.repository, "commit": spec.source.commit},
    }


@methods.command("list")
@json_option
def list_methods(as_json: bool) -> None:
    """Every method: the built-in ones, official implementations and plugins ("olatbench.methods"
    entry points), with its kind, a one-line description and its presets.

    \b
    Example:
      olatbench methods list
      olatbench methods list --json
    """
    from olatbench.methods.registry import method_names

    names = method_names()
    if not names:
        raise click.ClickException("no methods found; reinstall olatbench: pip install -e .")
    if as_json:
        click.echo(json.dumps([_method_json(name) for name in names], indent=2))
        return
    width = max(len(name) for name in names)
    for name in names:
        try:
            spec = _spec(name)
        except click.ClickException as error:
            click.echo(f"{name.ljust(width)}  (unavailable: {error.message})")
            continue
        summary = spec.description.strip().splitlines()[0:1]
        click.echo(f"{name.ljust(width)}  [{_kind(spec)}] {summary[0] if summary else ''}")
        code = _official_code(spec)
        if code is not None and not code.runnable:
            click.echo(f"{''.ljust(width)}  not runnable: {code.unsupported}")
            continue
        click.echo(f"{''.ljust(width)}  presets: {', '.join(spec.presets) or 'none'}")
    click.echo("Details: olatbench methods show NAME")


def _config_rows(
    config_class: type, resolved: Any = None, as_repr: bool = True
) -> list[tuple[str, str, Any, str, str]]:
    """(name, type, value, source, help) per config field: the value and its source from
    ``resolved`` (a `ResolvedConfig`), else the default; the value as ``repr`` text, or with
    ``as_repr=False`` as the value itself (None when the field is required)."""
    rows = []
    for field in dataclasses.fields(config_class):
        if resolved is not None:
            value, source = getattr(resolved.config, field.name), resolved.sources[field.name]
        elif field.default is not dataclasses.MISSING:
            value, source = field.default, "default"
        elif field.default_factory is not dataclasses.MISSING:
            value, source = field.default_factory(), "default"
        else:
            rows.append(
                (field.name, _type_name(field), "(required)" if as_repr else None, "", _help(field))
            )
            continue
        rows.append(
            (field.name, _type_name(field), repr(value) if as_repr else value, source, _help(field))
        )
    return rows


def _type_name(field: dataclasses.Field) -> str:
    return (
        field.type
        if isinstance(field.type, str)
        else getattr(field.type, "__name__", str(field.type))
    )


def _help(field: dataclasses.Field) -> str:
    return field.metadata.get("help", "") if field.metadata else ""


def _show_json(spec, resolved: Any) -> dict:
    """`_method_json` plus the config fields (each one's default, and its value and source in
    ``resolved``, a `ResolvedConfig` or None), each preset's values and, for official code, its
    commands."""
    from olatbench.methods.registry import config_class

    data = _method_json(spec.name)
    data["presets"] = {preset: dict(values) for preset, values in spec.presets.items()}
    try:
        config_type = config_class(spec)
        defaults = {
            name: value for name, _, value, _, _ in _config_rows(config_type, as_repr=False)
        }
        data["config"] = [
            {
                "name": name,
                "type": kind,
                "default": defaults[name],
                "value": value,
                "source": source,
                "help": help_text,
            }
            for name, kind, value, source, help_text in _config_rows(config_type, resolved, False)
        ]
    except Exception as error:  # a plugin's config module that does not import: say so
        data["config"], data["config_error"] = None, f"{type(error).__name__}: {error}"
    code = _official_code(spec)
    if code is not None:
        data["paper"] = code.paper
        data["runnable"], data["unsupported"] = code.runnable, code.unsupported or None
        data["commands"] = list(code.describe()) if code.runnable else []
    return data


def resolved_config(
    spec, suite_name: str | None, variant: str | None, settings: tuple[str, ...] = ()
) -> Any:
    """The `ResolvedConfig` of ``spec`` on ``suite_name`` (None: no suite) with ``variant`` and
    ``--set`` values, as a run resolves it; None when none of them is given (the defaults); a usage
    error naming what is wrong."""
    from olatbench.bench.plan import PlanError, parse_overrides, resolve_sources
    from olatbench.datasets.errors import DatasetError
    from olatbench.datasets.suites import get_suite

    if suite_name is None and variant is None and not settings:
        return None
    try:
        overrides = parse_overrides(settings)
        if suite_name is not None:
            return resolve_sources(
                spec, get_suite(suite_name), variant or "default", overrides=overrides
            )
        return spec.resolve_sources(variant, overrides)
    except (PlanError, DatasetError, KeyError, TypeError, ValueError) as error:
        raise click.UsageError(
            str(error.args[0] if isinstance(error, KeyError) else error)
        ) from None


def _derived(spec, folder: Path, iterations: int | None):
    """The preset ``run --data folder`` derives for ``spec`` (None: the method derives none); a
    usage error for a folder that is not a scene."""
    from olatbench.bench.plan import PlanError, derived_for_folder
    from olatbench.datasets.errors import DatasetError

    try:
        return derived_for_folder(spec, folder, iterations)
    except (DatasetError, PlanError) as error:
        raise click.UsageError(str(error)) from None


@methods.command("show")
@click.argument("name")
@click.option(
    "--data",
    "data_path",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    help="A scene folder of your own: also show the preset derived from it (as run --data uses it) "
    "and why each value was chosen.",
)
@click.option(
    "--iterations", type=click.IntRange(min=1), help="With --data: the run length asked for."
)
@click.option(
    "-s",
    "--suite",
    "suite_name",
    help="Resolve the config as a run on this suite does (its length and preset).",
)
@click.option(
    "--variant",
    help="Resolve the config with this variant (presets joined by '+', e.g. mini+official).",
)
@click.option(
    "--set", "settings", multiple=True, metavar="KEY=VALUE", help="A config value, as run --set."
)
@json_option
def show(
    name: str,
    data_path: Path | None,
    iterations: int | None,
    suite_name: str | None,
    variant: str | None,
    settings: tuple[str, ...],
    as_json: bool,
) -> None:
    """Config fields (type, value, and where the value came from: default, suite preset, variant,
    --set), presets (the fields each one changes), ablation grids, outputs and capabilities of
    method NAME; for an official implementation, the repository and commit it is pinned to.

    \b
    Example:
      olatbench methods show ssdgs
      olatbench methods show ssdgs --variant official          # values and their sources
      olatbench methods show ssdgs --suite mini --variant official
      olatbench methods show ssdgs --json    # the same as data (defaults as JSON values)
      olatbench methods show ssdgs --data captures/cup    # + your scene's preset, and why
    """
    from olatbench.methods.registry import config_class

    spec = _spec(name)
    if iterations is not None and data_path is None:
        raise click.UsageError("--iterations goes with --data")
    derived = _derived(spec, data_path, iterations) if data_path is not None else None
    resolved = resolved_config(spec, suite_name, variant, settings)
    if as_json:
        data = _show_json(spec, resolved)
        if data_path is not None:
            data["derived"] = (
                None
                if derived is None
                else {
                    field: {"value": derived.values.get(field), "why": why}
                    for field, why in derived.reasons.items()
                }
            )
        click.echo(json.dumps(data, indent=2, default=str))
        return
    click.echo(f"{name} [{_kind(spec)}]: {spec.description.strip()}")
    if spec.iterations is not None:
        click.echo(
            f"iterations: {spec.iterations} whatever the suite says"
            + (" (learning-free)" if spec.iterations == 0 else "")
        )
    click.echo(f"implementation: {spec.implementation}")
    if spec.source is not None:
        click.echo(
            f"source: github.com/{spec.source.repository} @ {spec.source.commit} "
            f"({spec.source.status})"
        )
        if spec.source.verified:
            click.echo(f"verified: {spec.source.verified}")
    code = _official_code(spec)
    if code is not None:
        click.echo(f"paper: {code.paper}")
        if not code.runnable:
            click.echo(f"not runnable: {code.unsupported}")
            return
        click.echo(
            "commands (in the checkout; <launcher> = the configured python, conda run or "
            "container):"
        )
        for line in code.describe():
            click.echo(f"  {line}")
    try:
        config_type = config_class(spec)
    # a plugin's config module that does not import: say so, show the rest
    except Exception as error:
        click.echo(f"config: {spec.config} (cannot be imported: {type(error).__name__}: {error})")
    else:
        asked = ", ".join(
            part
            for part in (
                suite_name and f"suite {suite_name}",
                variant and f"variant {variant}",
                settings and "--set",
            )
            if part
        )
        click.echo(
            f"config: {config_type.__name__}"
            + (f" ({asked})" if asked else "")
            + " (field, type, value, source)"
        )
        rows = _config_rows(config_type, resolved)
        if rows:
            widths = [max(len(str(row[i])) for row in rows) for i in range(4)]
            for row in rows:
                click.echo(
                    (
                        "  "
                        + "  ".join(
                            str(cell).ljust(width) for cell, width in zip(row, widths, strict=False)
                        )
                        + (f"  {row[4]}" if row[4] else "")
                    ).rstrip()
                )
    click.echo("presets:" if spec.presets else "presets: none")
    for preset, values in spec.presets.items():
        changes = ", ".join(f"{key}={value!r}" for key, value in values.items()) or "(defaults)"
        click.echo(f"  {preset}: {changes}")
    click.echo("ablation grids:" if spec.ablations else "ablation grids: none")
    for grid, variants in spec.ablations.items():
        reference = f" (compared with {variants.reference})" if variants.reference else ""
        click.echo(f"  {grid}: {', '.join(variants)}{reference}")
    if spec.scene_recipe is not None:
        click.echo(
            f"scenes of no suite (run --data): the {spec.scene_recipe} preset scaled to the scene "
            "(see it with --data DIR; docs/own-data.md)"
        )
    if data_path is not None:
        if derived is None:
            click.echo(
                f"{data_path}: {name} derives no preset from a scene; it takes its format's preset"
            )
        else:
            click.echo(f"preset derived from {data_path} (run -m {name} --data {data_path}):")
            for field, why in derived.reasons.items():
                click.echo(f"  {field} = {json.dumps(derived.values.get(field))}: {why}")
            click.echo(f"  as in the {derived.recipe} preset: {', '.join(derived.kept)}")
    click.echo(f"outputs: {', '.join(spec.outputs)}")
    click.echo(f"capabilities: {', '.join(sorted(spec.capabilities)) or 'none'}")
    if code is not None:
        click.echo(
            f"Run one: olatbench run --method {name} --suite mini --code checkout=PATH --code "
            "conda_env=NAME (settings: docs/official.md; check them: olatbench doctor)"
        )
        return
    click.echo(
        f"Run one: olatbench run --method {name} --suite mini [--variant PRESET]"
        + (f" [--ablation {next(iter(spec.ablations))}]" if spec.ablations else "")
    )


@methods.command("diff")
@click.argument("name")
@click.option(
    "-s",
    "--suite",
    "suite_name",
    help="Resolve the config as a run on this suite does (its length and preset).",
)
@click.option(
    "--variant",
    help="The variant to compare (presets joined by '+'; default: the config's defaults).",
)
@click.option(
    "--set", "settings", multiple=True, metavar="KEY=VALUE", help="A config value, as run --set."
)
@click.option(
    "--markdown", is_flag=True, help="Print the table as Markdown (as docs/ssdgs.md embeds it)."
)
@json_option
def diff(
    name: str,
    suite_name: str | None,
    variant: str | None,
    settings: tuple[str, ...],
    markdown: bool,
    as_json: bool,
) -> None:
    """Every config field of method NAME where it departs from the authors' code: our value and
    where it came from, the authors' value and the file:line that sets it, and the reason and
    measured effect recorded for the preset (olatbench/methods/<method>/authors.py). Fields the
    suite sets for both runners (length, budget, initialisation, density window) are listed apart;
    so are differences no field switches.

    \b
    Example:
      olatbench methods diff ssdgs --variant mini
      olatbench methods diff gs3 --variant mini --json
      olatbench methods diff ssdgs --suite mini --variant official    # nothing departs
    """
    from olatbench.methods.authors import departures

    spec = _spec(name)
    authors = spec.load_authors()
    if authors is None:
        raise click.UsageError(
            f"method '{name}' declares no authors' configuration to compare with; methods that "
            "do: olatbench methods show NAME (see docs/ssdgs.md, docs/baselines.md)"
        )
    resolved = resolved_config(spec, suite_name, variant, settings) or spec.resolve_sources(None)
    rows = departures(resolved, authors)
    if as_json:
        click.echo(json.dumps(_diff_json(spec, authors, rows), indent=2, default=str))
        return
    asked = (
        ", ".join(
            part
            for part in (
                suite_name and f"suite {suite_name}",
                variant and f"variant {variant}",
                settings and "--set",
            )
            if part
        )
        or "defaults"
    )
    head = (
        f"{name} ({asked}) against the authors' code, {authors.repository} @ {authors.commit[:7]}: "
        f"{len(rows)} field(s) depart"
    )
    notes = [
        "set by the suite for both runners (not compared): "
        f"{', '.join(sorted(authors.suite_fields))}",
        *(
            f"not switchable: {item.what}: the authors' {item.where}; here {item.native}"
            for item in authors.unswitchable
        ),
    ]
    if markdown:
        click.echo(
            "\n\n".join([head + ":", diff_markdown(rows), "\n".join(f"- {note}" for note in notes)])
        )
        return
    click.echo("\n".join([head, *([_diff_text(rows)] if rows else []), *notes]))


def _cell(value: Any) -> str:
    return json.dumps(value) if not isinstance(value, str) else value


def diff_markdown(rows) -> str:
    """The departures (`olatbench.methods.authors.DepartureRow`) as a Markdown table."""
    lines = [
        "| field | here | from | authors' | where | why | measured |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        why, effect = (
            (row.departure.reason, row.departure.effect)
            if row.departure
            else ("(none recorded)", "")
        )
        where = row.authors.where + (f" ({row.authors.note})" if row.authors.note else "")
        cells = [
            f"`{row.name}`",
            f"`{_cell(row.value)}`",
            row.source,
            f"`{_cell(row.authors.value)}`",
            where,
            why,
            effect,
        ]
        lines.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")
    return "\n".join(lines)


def _diff_text(rows) -> str:
    out = []
    for row in rows:
        out.append(
            f"  {row.name}: {_cell(row.value)} ({row.source}); authors' {_cell(row.authors.value)} "
            f"at {row.authors.where}" + (f" ({row.authors.note})" if row.authors.note else "")
        )
        if row.departure is not None:
            out.append(f"      why: {row.departure.reason}")
            out.append(f"      measured: {row.departure.effect}")
        else:
            out.append("      why: none recorded for this source")
    return "\n".join(out)


def _diff_json(spec, authors, rows) -> dict:
    return {
        "method": spec.name,
        "repository": authors.repository,
        "commit": authors.commit,
        "departures": [
            {
                "field": row.name,
                "value": row.value,
                "source": row.source,
                "authors": row.authors.value,
                "where": row.authors.where,
                "note": row.authors.note,
                "reason": row.departure.reason if row.departure else None,
                "effect": row.departure.effect if row.departure else None,
            }
            for row in rows
        ],
        "suite_fields": sorted(authors.suite_fields),
        "unswitchable": [
            {"what": u.what, "where": u.where, "native": u.native} for u in authors.unswitchable
        ],
    }
