"""Options shared by the verbs, so they are spelled alike everywhere.

* ``-o/--output`` for what a verb writes, ``--data-root`` for where scenes live, ``--resolution``
  for image sizes; the spellings used before (``--out``, ``--root``, ``--res``, ``--dest``) are
  still accepted but no longer shown in ``--help`` (`option` with ``aliases``).
* ``-q/--quiet`` on every verb with progress bars; ``TQDM_DISABLE`` (tqdm's own variable, any value
  but ``""``, ``0``, ``false``, ``no``) turns them off too (`show_progress`).
* ``--json`` on the verbs that list things (`json_option`).
* ``-s/--suite`` to restrict the verbs that read run folders (``status``, ``report``, ``view``) to
  one suite: built-in, ``[suites.NAME]`` of olatbench.toml or ``data-<format>``
  (`suite_filter_option`, `checked_suite`).
* ``--device`` defaults to ``auto`` on every verb that runs torch (`device_option`: its spelling
  checked), resolved by `resolved_device` (`olatbench.devices.resolve_device`) before anything runs:
  a device this machine lacks is a usage error.
* ``--resolution`` takes ``N`` (N×N) or ``WxH`` everywhere (`Resolution`).
* A mistyped option is offered the shown spellings only, never a hidden old one
  (`without_hidden_suggestions`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import click

from olatbench.datasets.sizes import parse_size

FALSE_WORDS = ("", "0", "false", "no", "off")


class AliasedOption(click.Option):
    """A click option accepting extra spellings (``hidden_aliases``) that ``--help`` does not
    show."""

    def __init__(self, *args: Any, hidden_aliases: tuple[str, ...] = (), **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.hidden_aliases = hidden_aliases

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        shown = self.opts
        self.opts = [name for name in shown if name not in self.hidden_aliases]
        try:
            return super().get_help_record(ctx)
        finally:
            self.opts = shown

    def get_error_hint(self, ctx: click.Context) -> str:
        return " / ".join(f"'{name}'" for name in self.opts if name not in self.hidden_aliases)


def option(*names: str, aliases: tuple[str, ...] = (), **kwargs: Any) -> Callable:
    """``click.option(*names, **kwargs)`` that also accepts the hidden old spellings ``aliases``."""
    return click.option(
        *names, *aliases, cls=AliasedOption, hidden_aliases=tuple(aliases), **kwargs
    )


def hidden_spellings(command: click.Command) -> set[str]:
    """The hidden old spellings (``--out``, …) of ``command``'s options."""
    return {
        alias
        for param in command.params
        if isinstance(param, AliasedOption)
        for alias in param.hidden_aliases
    }


def without_hidden_suggestions(error: click.NoSuchOption) -> click.NoSuchOption:
    """``error`` with the hidden old spellings removed from its "Did you mean" list (click offers
    every spelling its parser knows)."""
    if error.ctx is not None and error.possibilities:
        hidden = hidden_spellings(error.ctx.command)
        error.possibilities = [name for name in error.possibilities if name not in hidden]
    return error


class Resolution(click.ParamType):
    """An image size as ``N`` (N × N) or ``WxH``; converts to (width, height) of ``minimum`` to
    `olatbench.datasets.sizes.MAX_SIDE` pixels a side (`parse_size`)."""

    name = "N|WxH"

    def __init__(self, minimum: int = 1) -> None:
        self.minimum = minimum

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return self.name

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> tuple[int, int]:
        if isinstance(value, tuple):
            return value
        try:
            return parse_size(str(value), self.minimum)
        except ValueError as error:
            self.fail(str(error), param, ctx)


def tqdm_disabled() -> bool:
    """Whether ``$TQDM_DISABLE`` asks for no progress bars."""
    return os.environ.get("TQDM_DISABLE", "").strip().lower() not in FALSE_WORDS


def show_progress(quiet: bool) -> bool:
    """Progress bars on unless ``--quiet`` or ``$TQDM_DISABLE``."""
    return not quiet and not tqdm_disabled()


quiet_option = click.option(
    "--quiet",
    "-q",
    is_flag=True,
    help="No progress bars (also: TQDM_DISABLE=1 in the environment).",
)
json_option = click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")


def name_list(values: str | tuple[str, ...] | None, option: str) -> list[str] | None:
    """The comma-separated names of an option given once or several times (``--scenes a,b --scenes
    c``), spaces around each stripped; None when it was not given; a usage error naming ``option``
    when it was given but names nothing (``--scenes ''`` is no scene, never every scene)."""
    if values is None or values == ():
        return None
    given = (values,) if isinstance(values, str) else values
    names = [name.strip() for value in given for name in value.split(",") if name.strip()]
    if not names:
        raise click.BadParameter(
            f"{' '.join(map(repr, given))} names nothing; leave the option out for all",
            param_hint=f"'{option}'",
        )
    return names


def checked_suite(name: str | None) -> str | None:
    """``name`` when it names a suite (`olatbench.datasets.suites.get_suite`), else a usage error
    (exit 2) listing the known suites."""
    if name is None:
        return None
    from olatbench.datasets.errors import DatasetError
    from olatbench.datasets.suites import get_suite

    try:
        return get_suite(name).name
    except DatasetError as error:
        raise click.UsageError(str(error)) from None


suite_filter_option = click.option(
    "--suite",
    "-s",
    help="Only jobs of this suite (built-in, a [suites.NAME] of "
    "olatbench.toml, or data-<format> for run --data).",
)


class Device(click.ParamType):
    """A torch device name, its spelling checked without torch (`olatbench.devices.check_device`);
    whether this machine has it is checked when the verb resolves it (`resolved_device`)."""

    name = "DEVICE"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        from olatbench.devices import DeviceError, check_device

        try:
            return check_device(str(value))
        except DeviceError as error:
            self.fail(str(error), param, ctx)


def resolved_device(name: str) -> str:
    """``--device`` as torch will use it (`olatbench.devices.resolve_device`: auto resolved, the
    device tried); a usage error naming the option when this machine cannot use it."""
    from olatbench.devices import DeviceError, resolve_device

    try:
        return resolve_device(name)
    except DeviceError as error:
        raise click.BadParameter(str(error), param_hint="'--device'") from None


device_option = click.option(
    "--device",
    type=Device(),
    default="auto",
    show_default=True,
    help="torch device: auto (cuda when available, else cpu), cpu, cuda, cuda:1, ...",
)
