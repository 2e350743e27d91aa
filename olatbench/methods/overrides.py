"""Config overrides checked against the config dataclass's field types (``--set KEY=VALUE``).

The plan reads each VALUE as JSON where it can (``50``, ``true``, ``[1, 1, 1]``) and keeps the text
otherwise (`olatbench.bench.plan.parse_overrides`); `check_overrides` then fits every value to its
field's annotation, so a run never receives a value of the wrong type (unchecked, ``use_sss=False``
would arrive as the truthy string ``"False"`` and leave SSS on):

* ``bool``: ``true`` / ``false`` in any case (``False``, ``TRUE``); nothing else
  (``1``, ``yes``, ``maybe``);
* ``int``: a whole number (``50``, ``5e3``); never a bool or a fraction;
* ``float``: any finite number; never a bool, NaN or an infinity;
* ``str``: the text as written (``name=123`` is the text ``"123"``); ``Literal[...]``: one of its
  choices;
* ``tuple[X, ...]`` / ``tuple[X, Y, Z]``: a JSON list of fitting items (and of the right length);
* ``X | None``: ``null`` / ``none`` gives None, anything else must fit X.

A value that fits its type must also lie in the field's declared range (`olatbench.methods.ranges`:
e.g. a learning rate ≥ 0). Anything that does not fit is one `OverrideError` naming the field, the
value and the accepted form or range.
"""

from __future__ import annotations

import json
import math
import types
import typing
from dataclasses import fields
from typing import Any, Literal, Union

from olatbench.methods.ranges import field_range


class OverrideError(ValueError):
    """An override that names no field or does not fit its field's type (one clear message)."""


def check_overrides(
    config_type: type, overrides: dict[str, Any], method: str = ""
) -> dict[str, Any]:
    """``overrides`` with each value fitted to its field of the dataclass ``config_type``
    (module docstring)."""
    hints = typing.get_type_hints(config_type)
    names = {f.name for f in fields(config_type)}
    owner = f"method '{method}'" if method else config_type.__name__
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise OverrideError(
            f"{owner} has no config field {', '.join(unknown)}; its fields: "
            f"{', '.join(sorted(names))}. See: olatbench methods show {method or 'METHOD'}"
        )
    checked = {}
    for name, value in overrides.items():
        try:
            checked[name] = _fit(value, hints[name])
        except _Mismatch as mismatch:
            raise OverrideError(
                f"--set {name}={_shown(value)}: field '{name}' of {owner} takes {mismatch}"
            ) from None
        allowed = field_range(config_type, name)
        if allowed is not None and not allowed.contains(checked[name]):
            raise OverrideError(
                f"--set {name}={_shown(value)}: field '{name}' of {owner} must be "
                f"{allowed.describe()}"
            )
    return checked


class _Mismatch(Exception):
    """The accepted form, for the message."""


def _shown(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def _fit(value: Any, annotation: Any) -> Any:
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (Union, types.UnionType):
        options = [arg for arg in args if arg is not type(None)]
        if type(None) in args and (
            value is None or (isinstance(value, str) and value.lower() in ("null", "none"))
        ):
            return None
        for option in options:
            try:
                return _fit(value, option)
            except _Mismatch:
                continue
        forms = " or ".join(_form(option) for option in options)
        raise _Mismatch(forms + (" or null" if type(None) in args else ""))
    if origin is Literal:
        if value in args:
            return value
        raise _Mismatch(_form(annotation))
    if origin is tuple:
        if not isinstance(value, (list, tuple)):  # a tuple: already fitted (the plan checks twice)
            raise _Mismatch(_form(annotation))
        items = args[:1] * len(value) if len(args) == 2 and args[1] is Ellipsis else args
        if len(items) != len(value):
            raise _Mismatch(_form(annotation))
        try:
            return tuple(_fit(item, kind) for item, kind in zip(value, items, strict=True))
        except _Mismatch:
            raise _Mismatch(_form(annotation)) from None
    if annotation is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in ("true", "false"):
            return value.lower() == "true"
        raise _Mismatch(_form(bool))
    if annotation is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if isinstance(value, float) and math.isfinite(value) and value.is_integer():
            return int(value)
        raise _Mismatch(_form(int))
    if annotation is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise _Mismatch("a finite number")
            return float(value)
        raise _Mismatch(_form(float))
    if annotation is str:
        # name=123 means the text "123"
        return value if isinstance(value, str) else json.dumps(value)
    return value  # an annotation this checker does not know: the config's own validation applies


def _form(annotation: Any) -> str:
    """How a value of ``annotation`` is written on the command line."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is Literal:
        return "one of " + ", ".join(
            json.dumps(arg) if not isinstance(arg, str) else arg for arg in args
        )
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_form(args[0])} values, e.g. [1, 2]"
        return f"a list of {len(args)} values ({', '.join(_form(arg) for arg in args)})"
    return {bool: "true or false", int: "a whole number", float: "a number", str: "text"}.get(
        annotation, str(annotation)
    )
