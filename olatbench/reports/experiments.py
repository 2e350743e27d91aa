"""Report rows, one per experiment, and the one label rule every table, figure, legend and JSON
record uses.

Two jobs are the same experiment when they share method, variant, suite, protocol, resolved config
(iterations and every override are in it), resolution, code hash and official commit
(`olatbench.reports.collect.experiment_fields`) and, per scene, the data (its manifest hash). A
table cell aggregates only jobs of one experiment.

The label of an experiment (`experiment_labels`) names its method, its variant
(left out when ``default``) and, in parentheses, every setting that differs from the method's
defaults for its suite: the overrides the variant name carries (``--set`` / ``--iterations``:
``mini~iterations=200`` reads ``ssdgs/mini (iterations=200)``) and a resolution other than the
suite's own. Experiments that would still share a label get what differs between them added (``ssdgs
(iterations=5)`` / ``ssdgs (iterations=8)`` when the configs differ outside the variant name, e.g. a
changed default; ``code 1a2b3c4``; ``data v2`` for a scene whose data changed between jobs of one
experiment, data versions numbered per scene in order of first appearance). Two different
experiments never share a label.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping
from typing import Any

import pandas as pd

from olatbench.reports.published import VARIANT_LABELS

#: Variants whose paper label stands for the row in a table of one method (the ablation grids).
PAPER_VARIANT_PREFIXES = ("ablation-", "schedule-", "shadow-on-sss")

#: How each identity field is shown in a row label when it differs between rows of one
#: method/variant.
_SHOWN: dict[str, Callable[[Any], str]] = {
    "resolution": lambda value: f"resolution={value or '?'}",
    "protocol": lambda value: f"protocol {value}",
    "code": lambda value: f"code {value[:7] or '?'}",
    "official_commit": lambda value: f"commit {value[:7] or '?'}",
    "data_version": lambda value: f"data v{value}",
}


def _numbered(frame: pd.DataFrame, within: list[str], column: str) -> pd.Series:
    """Per frame row, 1, 2, … numbering the distinct values of ``column`` within each ``within``
    group, by first appearance."""
    seen_by_group: dict[tuple, dict[Any, int]] = {}
    numbers = []
    for *group, value in zip(*(frame[name] for name in within), frame[column], strict=True):
        seen = seen_by_group.setdefault(tuple(group), {})
        numbers.append(seen.setdefault(value, len(seen) + 1))
    return pd.Series(numbers, index=frame.index, dtype="int64")


def _facts(rows: pd.DataFrame) -> dict[str, str]:
    """The identity of one experiment as ``{field: shown text}`` (config entries one by one)."""
    first = rows.iloc[0]
    facts = {
        f"config.{key}": f"{key}={json.dumps(value, separators=(',', ':'))}"
        for key, value in sorted(json.loads(first["config"] or "{}").items())
    }
    for name, show in _SHOWN.items():
        facts[name] = show(first[name])
    return facts


def _difference_labels(keys: list[tuple], facts: dict[tuple, dict[str, str]]) -> dict[tuple, str]:
    """For experiments sharing one base label and suite: each one's ``k=v, …`` of the facts that
    differ."""
    names = list(dict.fromkeys(name for key in keys for name in facts[key]))
    missing = {name: f"{name.removeprefix('config.')}=—" for name in names}
    differing = [
        name for name in names if len({facts[key].get(name, missing[name]) for key in keys}) > 1
    ]
    return {
        key: ", ".join(facts[key].get(name, missing[name]) for name in differing) for key in keys
    }


def override_settings(variant: str) -> tuple[str, list[str]]:
    """``"mini~iterations=200,lr=0.1"`` (the runner's variant label,
    `olatbench.bench.plan.variant_label`) -> ``("mini", ["iterations=200", "lr=0.1"])``; a comma
    inside a value (``scale=[1,1,1]``) stays in it."""
    name, _, overrides = variant.partition("~")
    return name, [part for part in re.split(r",(?=[A-Za-z_][A-Za-z0-9_.]*=)", overrides) if part]


def _suite_resolution(suite: str) -> str | None:
    """The suite's own resolution as the collect frame writes it (``WxH`` or ``native``); None when
    the suite is unknown here (then any recorded resolution is shown)."""
    try:
        from olatbench.datasets.suites import get_suite

        resolution = get_suite(suite).resolution
    except (ImportError, KeyError, ValueError):
        return None
    return "native" if resolution is None else "x".join(str(int(v)) for v in resolution)


def _head_and_settings(row: Mapping[str, Any], paper_variants: bool) -> tuple[str, list[str]]:
    """The label of one experiment before disambiguation: ``method[/variant]`` (with
    ``paper_variants``, an ablation preset's paper label alone, e.g. ``A: Diff``) and the settings
    that differ from the suite's defaults."""
    name, settings = override_settings(str(row["variant"]))
    if paper_variants and name in VARIANT_LABELS and name.startswith(PAPER_VARIANT_PREFIXES):
        head = VARIANT_LABELS[name]
    else:
        head = row["method"] if name == "default" else f"{row['method']}/{name}"
    resolution = row.get("resolution", "")
    if resolution and resolution != _suite_resolution(str(row["suite"])):
        settings.append(_SHOWN["resolution"](resolution))
    return head, settings


def _joined(head: str, settings: list[str]) -> str:
    return f"{head} ({', '.join(settings)})" if settings else head


def experiment_labels(frame: pd.DataFrame, paper_variants: bool = False) -> pd.Series:
    """The label of each frame row (the module docstring's rule); ``paper_variants``: ablation
    presets read as the paper's labels without the method (the ablation table, which is of one
    method).

    Within each (method, variant, suite) the experiments are numbered by first appearance; a label
    unites the experiments of one number across suites (an ablation table spans suites, whose
    presets differ by design).
    """
    frame = frame.assign(
        setting=_numbered(frame, ["method", "variant", "suite"], "experiment"),
        data_version=_numbered(frame, ["experiment", "scene"], "data"),
    )
    row_columns = ["method", "variant", "setting", "data_version"]
    row_keys = list(zip(*(frame[column] for column in row_columns), strict=True))
    firsts: dict[tuple, dict[str, Any]] = {}
    for key, row in zip(row_keys, frame.to_dict("records"), strict=True):
        firsts.setdefault(key, row)
    shown = {key: _head_and_settings(row, paper_variants) for key, row in firsts.items()}
    base = {key: _joined(*parts) for key, parts in shown.items()}
    if len(set(base.values())) == len(base):
        return pd.Series([base[key] for key in row_keys], index=frame.index, dtype=object)
    facts = {key: _facts(rows) for key, rows in frame.groupby([*row_columns, "suite"], sort=False)}
    groups: dict[tuple[str, str], list[tuple]] = {}  # (base label, suite) -> experiment keys
    for key in facts:
        groups.setdefault((base[key[:4]], key[4]), []).append(key)
    differences: dict[tuple, list[str]] = {}
    for members in groups.values():
        for key, text in _difference_labels(members, facts).items():
            if text:
                differences.setdefault(key[:4], []).append(text)
    labels = {}
    for key, (head, settings) in shown.items():
        texts = list(dict.fromkeys(differences.get(key, [])))
        labels[key] = _joined(head, settings + ([" / ".join(texts)] if texts else []))
    # distinct experiments always differ somewhere; never merge silently
    if len(set(labels.values())) < len(labels):
        labels = {
            key: _joined(shown[key][0], [*shown[key][1], f"experiment {key[2]}.{key[3]}"])
            for key in labels
        }
    return pd.Series([labels[key] for key in row_keys], index=frame.index, dtype=object)
