"""``olatbench methods list`` and ``olatbench methods show NAME``."""

from __future__ import annotations

import dataclasses

import click


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def methods() -> None:
    """List the installed methods and show their presets and config fields.

    \b
    Examples:
      olatbench methods list
      olatbench methods show ssdgs
    """


def _load(name: str):
    from olatbench.methods.registry import get_method

    try:
        return get_method(name)
    except KeyError as error:
        raise click.ClickException(f"{error.args[0]}. See: olatbench methods list") from None
    except ImportError as error:
        raise click.ClickException(f"method '{name}' cannot be imported: {error}") from None


@methods.command("list")
def list_methods() -> None:
    """Every method found through the ``olatbench.methods`` entry points.

    \b
    Example:
      olatbench methods list
    """
    from olatbench.methods.registry import method_names

    names = method_names()
    if not names:
        raise click.ClickException("no methods installed; reinstall olatbench: pip install -e .")
    width = max(len(name) for name in names)
    for name in names:
        try:
            method_class = _load(name)
            summary = (method_class.description or "").strip().splitlines()[0:1]
            presets = ", ".join(method_class.presets) or "none"
            click.echo(f"{name.ljust(width)}  {summary[0] if summary else ''}")
            click.echo(f"{''.ljust(width)}  presets: {presets}")
        except click.ClickException as error:
            click.echo(f"{name.ljust(width)}  (unavailable: {error.message})")
    click.echo("Details: olatbench methods show NAME")


@methods.command("show")
@click.argument("name")
def show(name: str) -> None:
    """Config fields (type, default) and presets (the fields each one changes) of method NAME.

    \b
    Example:
      olatbench methods show ssdgs
    """
    method_class = _load(name)
    click.echo(f"{name}: {(method_class.description or '').strip()}")
    click.echo(f"config: {method_class.config_class.__name__}")
    rows = []
    for field in dataclasses.fields(method_class.config_class):
        if field.default is not dataclasses.MISSING:
            default = repr(field.default)
        elif field.default_factory is not dataclasses.MISSING:
            default = repr(field.default_factory())
        else:
            default = "(required)"
        kind = field.type if isinstance(field.type, str) else getattr(field.type, "__name__", str(field.type))
        help_text = field.metadata.get("help", "") if field.metadata else ""
        rows.append((field.name, kind, default, help_text))
    if rows:
        widths = [max(len(str(row[i])) for row in rows) for i in range(3)]
        for row in rows:
            click.echo("  " + "  ".join(str(cell).ljust(width) for cell, width in zip(row, widths, strict=False))
                       + (f"  {row[3]}" if row[3] else ""))
    click.echo("presets:" if method_class.presets else "presets: none")
    for preset, values in method_class.presets.items():
        changes = ", ".join(f"{key}={value!r}" for key, value in values.items()) or "(defaults)"
        click.echo(f"  {preset}: {changes}")
    click.echo(f"Run one: olatbench run --method {name} --suite mini [--variant PRESET]")
