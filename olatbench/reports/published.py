"""The SSD-GS paper's published numbers (ICLR 2026), shipped as package data.

``olatbench/reports/data/ssdgs_iclr2026.csv`` holds one row per printed number of the paper's
tables: ``table`` (the LaTeX label), ``method`` (as printed), ``suite``, ``scene`` ("Average" for
averages), ``split`` ("train", "test", or "-" for per-method facts), ``metric`` ("psnr", "ssim",
"lpips", "fps", "train_time", "gpu"), ``value`` (as printed: a number or text such as "RTX 4090"),
``std`` (the "± std" when printed) and ``paper_rank`` (1 red, 2 orange, empty: not coloured in the
paper).
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources
from pathlib import Path

import pandas as pd

CSV_NAME = "ssdgs_iclr2026.csv"
CSV_COLUMNS = ("table", "method", "suite", "scene", "split", "metric", "value", "std", "paper_rank")

# ``olatbench report --published-only --table NAME`` -> the paper's LaTeX label.
PAPER_TABLES: dict[str, str] = {
    "real": "tab:quantitative_real",
    "gs3": "tab:quantitative_synthetic",
    "sssgs": "tab:quantitative_synthetic_sss-gs",
    "sssgs-overview": "tab:quantitative_synthetic_sss-gs_overall",
    "ablation": "tab:ablation_study",
    "ablation-scenes": "tab:ablation_study_additional-scene",
    "shadow-on-sss": "tab:ablationstudy_shadow-on-sss",
    "relighting-baselines": "tab:quantitative_synthetic_relighting",
}

# Run variant (a method preset) -> the row label the paper prints for it.
VARIANT_LABELS: dict[str, str] = {
    "ablation-A": "A: Diff",
    "ablation-B": "B: D + S",
    "ablation-C": "C: D + S + SSS",
    "ablation-D": "D: Full (Ours)",
    "ablation-E": "E: Full - S",
    "ablation-F": "F: Full - SSS",
    "schedule-H": "H: Joint",
    "schedule-I": "I: Prog. Phys (Ours)",
    "schedule-J": "J: Prog. NonPhys",
    "schedule-K": "K: Prog. Merge",
    "shadow-on-sss": "Shadow-on-SSS",
    "sssgs": "Ours (w/ Opt)",
    "sssgs-no-opt": "Ours (w/o Opt)",
}

# The published tables in which a suite's per-scene numbers are looked up, most specific first.
SUITE_TABLES: dict[str, tuple[str, ...]] = {
    "nrhints": (
        "tab:quantitative_real",
        "tab:ablation_study",
        "tab:ablation_study_additional-scene",
        "tab:ablationstudy_shadow-on-sss",
    ),
    "gs3": (
        "tab:quantitative_synthetic",
        "tab:quantitative_synthetic_relighting",
        "tab:ablation_study_additional-scene",
        "tab:ablationstudy_shadow-on-sss",
    ),
    "sssgs": (
        "tab:quantitative_synthetic_sss-gs",
        "tab:quantitative_synthetic_sss-gs_overall",
        "tab:ablation_study_additional-scene",
        "tab:ablationstudy_shadow-on-sss",
    ),
}


class PublishedError(ValueError):
    """The published CSV is malformed, or a table name is unknown."""


def data_path() -> Path:
    """Where the packaged CSV lives."""
    return Path(str(resources.files("olatbench.reports").joinpath("data", CSV_NAME)))


def load_published(path: str | Path | None = None) -> pd.DataFrame:
    """The published numbers with the CSV's columns (``value`` as printed text, ``std`` float,
    ``paper_rank`` Int64).

    Rows keep the CSV's order, which is the paper's row and column order.
    """
    return _load(str(path or data_path()))[list(CSV_COLUMNS)].copy()


@lru_cache(maxsize=4)
def _load(path: str) -> pd.DataFrame:
    try:
        frame = pd.read_csv(
            path,
            dtype={"value": str, "std": str},
            keep_default_na=False,
            na_values={"paper_rank": [""]},
        )
    except FileNotFoundError:
        raise PublishedError(
            f"{path}: published numbers not found (is olatbench installed with its data?)"
        ) from None
    missing = [column for column in CSV_COLUMNS if column not in frame.columns]
    if missing:
        raise PublishedError(f"{path}: missing columns {', '.join(missing)}")
    frame = frame[list(CSV_COLUMNS)]
    frame["std_decimals"] = [_decimals(text) for text in frame["std"]]  # as printed: "0.10" has 2
    frame["std"] = pd.to_numeric(frame["std"].replace("", float("nan")), errors="raise").astype(
        float
    )
    frame["paper_rank"] = pd.to_numeric(frame["paper_rank"], errors="raise").astype("Int64")
    return frame


def table_id(name: str) -> str:
    """The LaTeX label of a paper table from its short name (``real``) or its label itself."""
    if name in PAPER_TABLES:
        return PAPER_TABLES[name]
    if name in PAPER_TABLES.values():
        return name
    raise PublishedError(f"unknown paper table {name!r}; choose one of {', '.join(PAPER_TABLES)}")


def published_table(name: str) -> pd.DataFrame:
    """The rows of one paper table, plus ``number`` (float, NaN for text values), ``decimals`` and
    ``std_decimals`` (as printed: the CSV keeps the paper's strings, e.g. ``0.040`` and
    ``61.50``)."""
    frame = _load(str(data_path())).copy()
    rows = frame[frame["table"] == table_id(name)].copy()
    rows["number"] = pd.to_numeric(rows["value"], errors="coerce")
    rows["decimals"] = [_decimals(text) for text in rows["value"]]
    return rows.reset_index(drop=True)


def _decimals(text: str) -> int:
    match = re.fullmatch(r"-?\d+(?:\.(\d+))?", text.strip())
    return len(match.group(1) or "") if match else 0


def normalise_name(name: str) -> str:
    """Case-, dash- and punctuation-insensitive key: "GS$^3$", "gs3" and "GS3" compare equal."""
    return re.sub(r"[^a-z0-9]", "", name.lower().replace("–", "-"))


def paper_method(
    method: str, variant: str | None = None, suite: str | None = None, fitted: bool = False
) -> str | None:
    """The paper's row label for a run's method, variant and suite, or None when the paper has no
    such row.

    ``ssdgs`` runs map to "Ours", or to the variant preset's label ("ablation-A" -> "A: Diff",
    "sssgs-no-opt" -> "Ours (w/o Opt)"). On the sssgs suite the row follows whether cameras and
    lights were refined: the native preset refines them ("Ours (w/ Opt)"); ``ssdgs-official``
    follows ``fitted``, whether the run's test views were scored with the poses its training fitted
    (results.json's ``evaluation.test_pose_fitting``: the flags of batch_script_synthetic_sssgs.py
    fit none, "Ours (w/o Opt)"; its ``opt`` variant's --cam_opt --pl_opt / --opt_pose do, "Ours
    (w/ Opt)"). Baselines match the paper's names ignoring case and punctuation ("gs3" -> "GS3"),
    the authors' code (``-official``) the row of its method.
    """
    if variant in VARIANT_LABELS:
        return VARIANT_LABELS[variant]
    official = method.endswith("-official")
    method = method.removesuffix("-official")
    if normalise_name(method) == "ssdgs":
        if suite != "sssgs":
            return "Ours"
        refined = fitted if official else True
        return "Ours (w/ Opt)" if refined else "Ours (w/o Opt)"
    wanted = normalise_name(method)
    for label in load_published()["method"].unique():
        if normalise_name(label) == wanted:
            return str(label)
    return None


def lookup(method_label: str, suite: str, scene: str, split: str, metric: str) -> float | None:
    """The paper's number for one cell, searching the suite's tables in order; None when not
    published.

    Scene and method names match ignoring case and punctuation.
    """
    frame = _load(str(data_path()))
    keys = (normalise_name(method_label), normalise_name(scene))
    for table in SUITE_TABLES.get(suite, ()):
        rows = frame[
            (frame["table"] == table) & (frame["split"] == split) & (frame["metric"] == metric)
        ]
        for _, row in rows.iterrows():
            if (normalise_name(row["method"]), normalise_name(row["scene"])) == keys:
                number = pd.to_numeric(row["value"], errors="coerce")
                return None if pd.isna(number) else float(number)
    return None
