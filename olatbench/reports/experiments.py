"""Report rows, one per experiment: a table cell aggregates only jobs that are identical but for the seed.

Two jobs are the same experiment when they share method, variant, suite, protocol, resolved config (iterations and
every override are in it), resolution, code hash and official commit (`olatbench.reports.collect.experiment_fields`)
and, per scene, the data (its manifest hash). A method/variant run as several experiments gets one row per
experiment, each labelled by what differs from the others, e.g. ``ssdgs (iterations=5)`` and
``ssdgs (iterations=8)``; a scene whose data changed between jobs of one experiment gives a row ``(data v2)``
holding the jobs of the second data version (data versions are numbered per scene in order of first appearance).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import pandas as pd

#: How each identity field is shown in a row label when it differs between rows of one method/variant.
_SHOWN: dict[str, Callable[[Any], str]] = {
    "resolution": lambda value: f"resolution={value or '?'}",
    "protocol": lambda value: f"protocol {value}",
    "code": lambda value: f"code {value[:7] or '?'}",
    "official_commit": lambda value: f"commit {value[:7] or '?'}",
    "data_version": lambda value: f"data v{value}",
}


def _numbered(frame: pd.DataFrame, within: list[str], column: str) -> pd.Series:
    """Per frame row, 1, 2, … numbering the distinct values of ``column`` within each ``within`` group, by first
    appearance."""
    seen_by_group: dict[tuple, dict[Any, int]] = {}
    numbers = []
    for *group, value in zip(*(frame[name] for name in within), frame[column], strict=True):
        seen = seen_by_group.setdefault(tuple(group), {})
        numbers.append(seen.setdefault(value, len(seen) + 1))
    return pd.Series(numbers, index=frame.index, dtype="int64")


def _facts(rows: pd.DataFrame) -> dict[str, str]:
    """The identity of one experiment as ``{field: shown text}`` (config entries one by one)."""
    first = rows.iloc[0]
    facts = {f"config.{key}": f"{key}={json.dumps(value, separators=(',', ':'))}"
             for key, value in sorted(json.loads(first["config"] or "{}").items())}
    for name, show in _SHOWN.items():
        facts[name] = show(first[name])
    return facts


def _difference_labels(keys: list[tuple], facts: dict[tuple, dict[str, str]]) -> dict[tuple, str]:
    """For experiments sharing one base label and suite: each one's ``k=v, …`` of the facts that differ."""
    names = list(dict.fromkeys(name for key in keys for name in facts[key]))
    missing = {name: f"{name.removeprefix('config.')}=—" for name in names}
    differing = [name for name in names if len({facts[key].get(name, missing[name]) for key in keys}) > 1]
    return {key: ", ".join(facts[key].get(name, missing[name]) for name in differing) for key in keys}


def experiment_rows(frame: pd.DataFrame, base_label: Callable[[str, str], str]) -> pd.Series:
    """The row label of each frame row: ``base_label(method, variant)``, then, where one method/variant was run as
    several experiments (or on several data versions of a scene), `` (what differs)`` (parentheses: no format
    escapes them).

    Within each (method, variant, suite) the experiments are numbered by first appearance; a row unites the
    experiments of one number across suites (an ablation table spans suites, whose presets differ by design).
    """
    frame = frame.assign(setting=_numbered(frame, ["method", "variant", "suite"], "experiment"),
                         data_version=_numbered(frame, ["experiment", "scene"], "data"))
    row_columns = ["method", "variant", "setting", "data_version"]
    row_keys = list(zip(*(frame[column] for column in row_columns), strict=True))
    base = {key: base_label(key[0], key[1]) for key in dict.fromkeys(row_keys)}
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
    for key, label in base.items():
        texts = list(dict.fromkeys(differences.get(key, [])))
        labels[key] = f"{label} ({' / '.join(texts)})" if texts else label
    if len(set(labels.values())) < len(labels):  # distinct experiments always differ somewhere; never merge silently
        labels = {key: f"{label} (experiment {key[2]}.{key[3]})" for key, label in labels.items()}
    return pd.Series([labels[key] for key in row_keys], index=frame.index, dtype=object)
