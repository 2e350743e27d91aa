"""The paper's tables from a user's runs (the long frame of `olatbench.reports.collect.collect`).

* `scene_table`: methods × scenes × {Train, Test}, one block per metric, optional Average column.
* `overview_table`: per-split averages over scenes (mean ± std), render FPS, training time, device.
* `ablation_table`: the runs of a method's ablation grids as rows, one rule between grids, each
  compared with its grid's reference variant (both as each job.json records them: the
  ``ablation_grid`` / ``ablation_reference`` columns of `olatbench.reports.collect`); for SSD-GS,
  compositions A–F and schedules H–K. One scene gives the paper's Table 2 layout, several scenes the
  appendix layout with an Average column.

Missing or failed runs never silently change a number: a cell without a finished run prints "—" with
a footnote mark, a mean over fewer seeds than expected is marked, and an average over scenes is only
computed when every scene has a value. Numbers scored with test poses/lights fitted to the test
images (interleaved fitting during training, or post-hoc test-time refinement) carry their own
marks, also on every average that includes one. With ``published=True`` each run row that the paper
also reports gets a "(paper)" row and a "Δ" row (run − paper) beneath it; those rows are never
ranked. With ``versus`` (a row) every other row gets a "Δ" row against it instead, each cell marked
within or beyond seed noise.
"""

from __future__ import annotations

import itertools
import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import pandas as pd

from olatbench.metrics.registry import find_metric
from olatbench.names import did_you_mean, match_name
from olatbench.reports.experiments import experiment_labels
from olatbench.reports.layouts import (
    CellLookup,
    metric_columns_layout,
    overview_layout,
    scenes_layout,
    split_rows_layout,
)
from olatbench.reports.model import Cell, Table
from olatbench.reports.published import lookup, normalise_name, paper_method

#: An ablation cell's difference from the full model counts as significant when it exceeds this many
#: pooled sample standard deviations over seeds (a two-sided 5 % t-test with 3 + 3 seeds needs
#: t(0.975, 4) · √(2/3) ≈ 2.3; 2 is the usual rule of thumb and errs towards calling an effect
#: real).
SIGNIFICANCE_FACTOR = 2.0
NOTE_TEXTS = {
    "a": "the run failed (see the failures listed below and the job's error.txt)",
    "b": "no run found for this cell",
    "c": (
        "mean over the finished seeds only (others failed, have not finished or are missing); an "
        "average marked c includes such a scene"
    ),
    "r": (
        "the run has not finished (running, interrupted or only planned; see the jobs listed below)"
    ),
    "d": "average not computed: at least one scene has no value",
    "e": "the run did not compute this metric (null in results.json, e.g. LPIPS weights missing)",
    "s": (
        "differs from its reference (an ablation grid's full model, or the --versus row) by more "
        f"than {SIGNIFICANCE_FACTOR:g}× the pooled sample std over seeds: the effect exceeds seed "
        "noise"
    ),
    "n": (
        "differs from its reference (an ablation grid's full model, or the --versus row) by at "
        f"most {SIGNIFICANCE_FACTOR:g}× the pooled sample std over seeds: within seed noise"
    ),
    "f": "scored with the test views' poses and lights fitted to the test images during training "
    "(test_pose_fitting=interleaved, the official code's real-data protocol); not comparable with "
    "raw poses",
    "g": "scored after post-hoc test-time refinement of the test views' poses and lights against "
    "their images (test_time_refinement); not comparable with raw poses",
}
#: Footnote of each way of posing scored views (the ``test_poses`` column of `collect`).
POSE_NOTES = {"fitted": "f", "refined": "g"}


class ReportError(ValueError):
    """The runs cannot make the requested table (nothing selected, several suites, ...)."""


@dataclass
class Notes:
    """Footnote marks used in one table, in order of first use."""

    used: dict[str, str] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)
    unfinished: list[str] = field(default_factory=list)

    def mark(self, letter: str) -> tuple[str, ...]:
        self.used.setdefault(letter, NOTE_TEXTS[letter])
        return (letter,)

    def lines(self) -> list[str]:
        lines = [f"{letter}: {text}." for letter, text in sorted(self.used.items())]
        for title, jobs in (("Failed", self.failures), ("Not finished", self.unfinished)):
            shown = jobs[:10]
            lines += [f"{title}: {job}" for job in shown]
            if len(jobs) > len(shown):
                lines.append(f"… and {len(jobs) - len(shown)} more jobs {title.lower()}.")
        return lines


def select_runs(
    frame: pd.DataFrame, suite: str | None = None, methods: Sequence[str] | None = None
) -> pd.DataFrame:
    """Rows of one suite and of the named methods ("ssdgs" or "ssdgs/variant", `checked_names`:
    "3DGS" is 3dgs); a `ReportError` if none, or when a name matches no run
    (with a "did you mean")."""
    selected = frame
    if suite is not None:
        selected = selected[selected["suite"] == suite]
    if methods:
        keys = frame["method"] + "/" + frame["variant"]
        methods = checked_names(methods, [*frame["method"], *keys], "--methods", "method")
        keys = selected["method"] + "/" + selected["variant"]
        selected = selected[selected["method"].isin(methods) | keys.isin(methods)]
    if selected.empty:
        found = sorted(set(frame["suite"])) if suite else sorted(set(frame["method"]))
        raise ReportError(
            f"no results match suite={suite!r} methods={list(methods or [])}; the runs hold "
            f"{'suites' if suite else 'methods'} {', '.join(found) or 'none'}"
        )
    return selected


def checked_names(
    requested: Sequence[str], known: Iterable[str], option: str, what: str
) -> list[str]:
    """``requested`` as ``known`` spells them (`olatbench.names.match_name`: ignoring case where
    only one matches); a `ReportError` naming ``option``, with a "did you mean" and the known names,
    for one that matches none."""
    known = sorted({name for name in known if name})
    matched = []
    for name in requested:
        found = match_name(name, known)
        if found is None:
            raise ReportError(
                f"{option}: unknown {what} {name!r}{did_you_mean(name, known)}; known here: "
                f"{', '.join(known) or 'none'}"
            )
        matched.append(found)
    return matched


def checked_blocks(
    frame: pd.DataFrame, metrics: Sequence[str] | None, splits: Sequence[str] | None
) -> tuple[list[str] | None, list[str] | None]:
    """``--metrics`` and ``--splits`` checked (`checked_names`) against what a table can show: the
    metrics of every protocol and the splits ``train`` and ``test``, with those the runs hold
    (their per-job facts aside)."""
    from olatbench.metrics.protocols import get_protocol, protocol_names

    scored = frame[~frame["split"].isin(("-", ""))]
    known_metrics = [
        *(metric for name in protocol_names() for metric in get_protocol(name).metrics),
        *scored["metric"],
    ]
    return (
        checked_names(metrics, known_metrics, "--metrics", "metric") if metrics else None,
        checked_names(splits, ["train", "test", *scored["split"]], "--splits", "split")
        if splits
        else None,
    )


def single_suite(frame: pd.DataFrame) -> str:
    suites = sorted(set(frame["suite"]))
    if len(suites) != 1:
        raise ReportError(
            f"the selected runs span several suites ({', '.join(suites)}); choose one with --suite"
        )
    return suites[0]


def expected_scenes(suite: str, found: Sequence[str]) -> tuple[list[str], str | None]:
    """The suite's scenes (canonical order) and a footnote when they had to be taken from the
    runs."""
    try:
        from olatbench.datasets.suites import get_suite

        scenes = list(get_suite(suite).scenes)
    except (ImportError, KeyError, ValueError) as error:
        return sorted(
            set(found), key=list(found).index
        ), f"scene list taken from the runs ({error})"
    known = {normalise_name(scene) for scene in scenes}
    extra = [scene for scene in dict.fromkeys(found) if normalise_name(scene) not in known]
    return scenes + extra, None


class RunCells:
    """Per-cell means over seeds (and over scenes for averages) with their footnote marks."""

    def __init__(
        self, frame: pd.DataFrame, seeds: str = "mean", paper_variants: bool = False
    ) -> None:
        """``paper_variants``: rows of ablation presets are labelled as in the paper
        (`experiment_labels`)."""
        if seeds not in ("mean", "all"):
            raise ReportError(f"seeds must be 'mean' or 'all', not {seeds!r}")
        self.notes = Notes()
        frame = frame.copy()
        frame["row"] = experiment_labels(frame, paper_variants)
        if seeds == "all":
            frame["row"] = frame["row"] + " seed" + frame["seed"].astype(str)
        self.frame = frame
        self.rows = list(dict.fromkeys(frame["row"]))
        self.source = {
            row: (group["method"].iloc[0], group["variant"].iloc[0])
            for row, group in frame.groupby("row")
        }
        self.seeds = {row: sorted(set(group["seed"])) for row, group in frame.groupby("row")}
        # named with their cell: row, scene, seed
        for _, job in frame[frame["status"] != "done"].iterrows():
            listed = self.notes.failures if job["status"] == "failed" else self.notes.unfinished
            listed.append(f"{job['row']} on {job['scene']}, seed {job['seed']} — {job['error']}")

    def fitted(self, row: str) -> bool:
        """Whether the row's test numbers were scored with test views fitted during training
        (``test_poses``)."""
        frame = self.frame
        return bool(frame.loc[frame["row"] == row, "test_poses"].str.contains("fitted").any())

    def jobs(self, row: str, scene: str) -> pd.DataFrame:
        frame = self.frame
        return frame[
            (frame["row"] == row) & (frame["scene"].map(normalise_name) == normalise_name(scene))
        ]

    def cell(
        self,
        row: str,
        scene: str,
        split: str,
        metric: str,
        *,
        with_std: bool = False,
        note: bool = True,
    ) -> Cell:
        """Mean over seeds of one (row, scene, split, metric), marked when anything is missing.

        ``with_std`` adds the sample std over seeds (ddof=1); ``note=False`` leaves no footnote mark
        (for cells only used inside an average).
        """
        mark = self.notes.mark if note else (lambda letter: ())
        jobs = self.jobs(row, scene)
        done = jobs[jobs["status"] == "done"]
        values = done[(done["split"] == split) & (done["metric"] == metric)]
        numbers = values["value"].dropna()
        if numbers.empty:
            if jobs.empty:
                return Cell(None, marks=mark("b"))
            if done.empty:
                return Cell(None, marks=mark("a" if (jobs["status"] == "failed").any() else "r"))
            return Cell(None, marks=mark("e" if not values.empty else "b"))
        complete = self._complete(row, scene, split, metric)
        std = float(numbers.std(ddof=1)) if with_std and len(numbers) > 1 else None
        marks = (() if complete else mark("c")) + self._pose_marks(values, note)
        return Cell(float(numbers.mean()), std=std, marks=marks)

    def _pose_marks(self, values: pd.DataFrame, note: bool = True) -> tuple[str, ...]:
        """Footnote marks for the ways the scored views in ``values`` were posed
        (none for raw poses)."""
        modes = {
            part
            for text in values.get("test_poses", pd.Series(dtype=str)).fillna("")
            for part in str(text).split("+")
            if part
        }
        letters = sorted(POSE_NOTES[mode] for mode in modes if mode in POSE_NOTES)
        return (
            tuple(m for letter in letters for m in self.notes.mark(letter))
            if note
            else tuple(letters)
        )

    def seed_values(
        self, row: str, scenes: Sequence[str], split: str, metric: str
    ) -> dict[int, float]:
        """Per seed, the mean over ``scenes`` of one (row, split, metric); seeds missing a scene are
        left out."""
        done = self.frame[
            (self.frame["row"] == row)
            & (self.frame["status"] == "done")
            & (self.frame["split"] == split)
            & (self.frame["metric"] == metric)
        ].dropna(subset=["value"])
        done = done[
            done["scene"].map(normalise_name).isin({normalise_name(scene) for scene in scenes})
        ]
        per_seed = done.groupby("seed")["value"].agg(["mean", "count"])
        return {
            int(seed): float(mean)
            for seed, (mean, count) in per_seed.iterrows()
            if count == len(scenes)
        }

    def average(
        self, row: str, scenes: Sequence[str], split: str, metric: str, with_std: bool = False
    ) -> Cell:
        """Mean (± population std, ``with_std`` and two or more scenes) over scenes of the per-scene
        means; "—" unless every scene has a value."""
        numbers, partial, posed = [], False, set()
        for scene in scenes:
            cell = self.cell(row, scene, split, metric, note=False)
            if cell.number is None:
                return Cell(None, marks=self.notes.mark("d"))
            numbers.append(cell.number)
            partial |= not self._complete(row, scene, split, metric)
            posed |= set(cell.marks) & set(POSE_NOTES.values())
        mean = sum(numbers) / len(numbers)
        spread = with_std and len(numbers) > 1  # one scene has no spread: no "± 0.0000"
        std = math.sqrt(sum((n - mean) ** 2 for n in numbers) / len(numbers)) if spread else None
        marks = (self.notes.mark("c") if partial else ()) + tuple(
            m for letter in sorted(posed) for m in self.notes.mark(letter)
        )
        return Cell(mean, std=std, marks=marks)

    def _complete(self, row: str, scene: str, split: str, metric: str) -> bool:
        """Whether every seed of the row has a value for this scene
        (else the seed mean is partial)."""
        jobs = self.jobs(row, scene)
        values = jobs[
            (jobs["status"] == "done") & (jobs["split"] == split) & (jobs["metric"] == metric)
        ]
        return set(values.dropna(subset=["value"])["seed"]) >= set(self.seeds[row])


def seed_counts(run_cells: RunCells) -> dict[str, dict[str, int]]:
    """Row -> scene -> how many seeds the row's cell of that scene averages
    (finished jobs with a number)."""
    frame = run_cells.frame
    done = frame[(frame["status"] == "done") & (frame["split"] != "-")].dropna(subset=["value"])
    counts: dict[str, dict[str, int]] = {row: {} for row in run_cells.rows}
    for (row, scene), group in done.groupby(["row", "scene"], sort=False):
        counts[row][scene] = int(group["seed"].nunique())
    return counts


def seed_text(run_cells: RunCells, seeds: str, seed_std: bool = False) -> str:
    """What each cell averages, counted truthfully: ``mean ± sample std over 3 seeds``, or, when
    cells differ, ``mean ± sample std over 1–3 seeds per cell`` followed by each row's counts.
    ``seed_std``: the cells carry the sample std over seeds where they have several
    (a one-seed cell never does)."""
    if seeds == "all":
        return "every seed as its own row"
    counts = seed_counts(run_cells)
    numbers = sorted({n for per_scene in counts.values() for n in per_scene.values()})
    if not numbers:
        return "no finished seeds"
    spread = " ± sample std" if seed_std and numbers[-1] > 1 else ""
    if len(numbers) == 1:
        return f"mean{spread} over {numbers[0]} seed{'s' if numbers[0] > 1 else ''}"
    per_row = "; ".join(
        _row_seed_counts(row, per_scene) for row, per_scene in counts.items() if per_scene
    )
    note = " (a one-seed cell has no ±)" if spread else ""
    return (
        f"mean{spread} over {numbers[0]}–{numbers[-1]} seeds per cell{note} — seeds per cell: "
        f"{per_row}"
    )


def _row_seed_counts(row: str, per_scene: dict[str, int]) -> str:
    """``ssdgs 3 (Cat 2)``: the row's usual seed count, then the scenes that have another."""
    usual = max(set(per_scene.values()), key=list(per_scene.values()).count)
    others = ", ".join(f"{scene} {n}" for scene, n in per_scene.items() if n != usual)
    return f"{row} {usual}" + (f" ({others})" if others else "")


def _protocol_line(run_cells: RunCells, suite: str, seeds: str, seed_std: bool = False) -> str:
    """The table's protocol line: metric protocols, suite and `seed_text`."""
    protocols = sorted(set(run_cells.frame["protocol"]))
    text = f"{', '.join(protocols)}; suite {suite}; {seed_text(run_cells, seeds, seed_std)}"
    if len(protocols) > 1:
        text += " — WARNING: mixed metric protocols, numbers are not comparable"
    return text


def _add_published(
    cells: dict,
    rows: list[str],
    run_cells: RunCells,
    suite: str | Mapping[str, str],
    keys: Sequence[tuple[str, str]],
    metrics: Sequence[str],
    ranks: dict[str, str | None],
) -> list[str]:
    """Insert "(paper)" and "Δ" rows after each run row the paper reports; returns the new row
    order.

    ``suite`` is the suite of every scene, or a mapping scene -> suite (ablations span suites).
    """
    ordered = []
    for row in rows:
        ordered.append(row)
        method, variant = run_cells.source[row]
        row_suite = suite if isinstance(suite, str) else next(iter(suite.values()), None)
        label = paper_method(method, variant, row_suite, fitted=run_cells.fitted(row))
        if label is None:
            continue
        paper_row, delta_row = f"{label} (paper)", f"Δ {row} − paper"
        found = False
        for scene, split in keys:
            for metric in metrics:
                scene_suite = suite if isinstance(suite, str) else suite.get(scene, "")
                number = (
                    None if scene == "Average" else lookup(label, scene_suite, scene, split, metric)
                )
                if scene == "Average":
                    numbers = [
                        cells[(paper_row, s, split, metric)].number
                        for s, sp in keys
                        if sp == split and s != "Average" and (paper_row, s, split, metric) in cells
                    ]
                    expected = len({s for s, _ in keys if s != "Average"})
                    number = (
                        sum(numbers) / len(numbers)
                        if numbers and None not in numbers and len(numbers) == expected
                        else None
                    )
                found |= number is not None
                cells[(paper_row, scene, split, metric)] = Cell(number)
                ours = cells.get((row, scene, split, metric), Cell(None)).number
                cells[(delta_row, scene, split, metric)] = Cell(
                    None if ours is None or number is None else ours - number, signed=True
                )
        if found:
            ordered += [paper_row, delta_row]
            ranks[paper_row] = ranks[delta_row] = None
    return ordered


def versus_row(run_cells: RunCells, name: str) -> str:
    """The row that ``name`` (``--versus``) means: a row label as the table prints it, or
    ``method`` / ``method/variant`` when exactly one row has it (`olatbench.names.match_name`:
    ignoring case where only one matches); a `ReportError` listing the rows otherwise."""
    rows = run_cells.rows
    label = match_name(name, rows)
    if label is not None:
        return label
    matches = [
        row
        for row in rows
        if match_name(name, [run_cells.source[row][0], "/".join(run_cells.source[row])])
    ]
    if len(matches) == 1:
        return matches[0]
    listed = "; ".join(rows)
    if matches:
        raise ReportError(
            f"--versus {name!r} matches {len(matches)} rows ({'; '.join(matches)}): give the "
            "row's label as the table prints it"
        )
    raise ReportError(f"--versus: no row {name!r}{did_you_mean(name, rows)}; the rows: {listed}")


def _add_versus(
    cells: dict,
    rows: list[str],
    run_cells: RunCells,
    reference: str,
    columns: Sequence[tuple[str, Sequence[str]]],
    splits: Sequence[str],
    metrics: Sequence[str],
    ranks: dict[str, str | None],
) -> list[str]:
    """Insert "Δ ROW − ``reference``" beneath every other row; returns the new row order.

    A Δ cell is the difference of the two cells above it (means over seeds), marked by
    `_noise_marks`; ``columns`` maps each printed column (a scene or "Average") to the scenes it
    averages, so an Average is tested on the per-seed averages. Δ rows are never ranked.
    """
    ordered = []
    for row in rows:
        ordered.append(row)
        if row == reference:
            continue
        delta = f"Δ {row} − {reference}"
        for column, scenes in columns:
            for split in splits:
                for metric in metrics:
                    ours = cells[(row, column, split, metric)].number
                    theirs = cells[(reference, column, split, metric)].number
                    if ours is None or theirs is None:
                        cells[(delta, column, split, metric)] = Cell(None, signed=True)
                        continue
                    marks = _noise_marks(run_cells, row, reference, scenes, split, metric)
                    cells[(delta, column, split, metric)] = Cell(
                        ours - theirs, signed=True, marks=marks
                    )
        ordered.append(delta)
        ranks[delta] = None
    return ordered


def scene_table(
    frame: pd.DataFrame,
    *,
    suite: str | None = None,
    methods: Sequence[str] | None = None,
    metrics: Sequence[str] = ("psnr", "ssim", "lpips"),
    splits: Sequence[str] = ("train", "test"),
    seeds: str = "mean",
    average: bool = False,
    published: bool = False,
    versus: str | None = None,
) -> Table:
    """Methods × scenes × splits with one block per metric (the paper's Table 1 layout).

    ``published``: a "(paper)" and a "Δ … − paper" row beneath each row the paper reports.
    ``versus`` (a row, `versus_row`): a "Δ ROW − versus" row beneath every other row, each cell
    marked within or beyond seed noise (`significance_mark`); not with ``published`` or
    ``seeds="all"`` (one seed per row has no spread).
    """
    if versus is not None and (published or seeds == "all"):
        raise ReportError("--versus compares means over seeds: not with --published or --seeds all")
    selected = select_runs(frame, suite, methods)
    suite = suite or single_suite(selected)
    run_cells = RunCells(selected, seeds)
    scenes, scene_note = expected_scenes(suite, list(selected["scene"]))
    cells, rows = {}, list(run_cells.rows)
    for row in rows:
        for scene in scenes:
            for split in splits:
                for metric in metrics:
                    cells[(row, scene, split, metric)] = run_cells.cell(
                        row, scene, split, metric, with_std=True
                    )
        if average:
            for split in splits:
                for metric in metrics:
                    cells[(row, "Average", split, metric)] = run_cells.average(
                        row, scenes, split, metric
                    )
    columns = scenes + (["Average"] if average else [])
    ranks: dict[str, str | None] = {row: "all" for row in rows}
    versus_note = []
    if versus is not None:
        reference = versus_row(run_cells, versus)
        spans = [(scene, [scene]) for scene in scenes] + ([("Average", scenes)] if average else [])
        rows = _add_versus(cells, rows, run_cells, reference, spans, splits, metrics, ranks)
        versus_note = [
            f"Δ rows: the row above − {reference} (means over seeds); not ranked. A Δ marked s "
            "or n was tested against seed noise; unmarked: fewer than two seeds on a side."
        ]
    if published:
        rows = _add_published(
            cells,
            rows,
            run_cells,
            suite,
            [(s, sp) for s in columns for sp in splits],
            metrics,
            ranks,
        )
    if published:
        has_paper = len(rows) > len(run_cells.rows)
        table_notes = [
            "(paper) rows: SSD-GS (ICLR 2026) as printed; Δ rows: run − paper; neither is ranked."
            if has_paper
            else f"--published: the paper reports none of these methods on {suite}."
        ]
    else:
        table_notes = []
    table = scenes_layout(
        CellLookup(cells),
        rows,
        columns,
        splits,
        metrics,
        name=f"tab:{suite}",
        caption=f"Per-scene results on the {suite} suite.",
        protocol=_protocol_line(run_cells, suite, seeds, seed_std=True),
        rank_sets=ranks,
    )
    table.footnotes += (
        table_notes + versus_note + ([scene_note] if scene_note else []) + run_cells.notes.lines()
    )
    return table


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.2f} h" if seconds >= 3600 else f"{seconds / 60:.1f} min"


def published_overview_cells(suite: str, metrics: Sequence[str], splits: Sequence[str]) -> dict:
    """The paper's overview rows for a suite, keyed like `overview_table`'s cells
    ("<method> (paper)").

    SSS-GS: the paper's Table 1(c) as printed. NRHints / GS3: mean ± population std over the scenes
    of Table 1(a) / 1(b) (the paper prints no overview there, so FPS, time and GPU stay "—").
    """
    from olatbench.reports.published import published_table

    cells: dict = {}
    if suite == "sssgs":
        rows = published_table("sssgs-overview")
        for _, row in rows.iterrows():
            label = f"{row['method']} (paper)"
            split = "-" if row["metric"] in ("train_time", "gpu", "fps") else row["split"]
            std = None if pd.isna(row["std"]) else float(row["std"])
            value = str(row["value"]) if pd.isna(row["number"]) else float(row["number"])
            decimals = (
                4
                if std is None and find_metric(row["metric"]) is not None
                else int(row["decimals"])
            )
            cells[(label, "Average", split, row["metric"])] = Cell(
                value, std=std, decimals=decimals
            )
        return cells
    table = {"nrhints": "real", "gs3": "gs3"}.get(suite)
    if table is None:
        return cells
    rows = published_table(table)
    for (method, split, metric), group in rows.groupby(["method", "split", "metric"], sort=False):
        if split in splits and metric in metrics:
            numbers = group["number"].astype(float)
            cells[(f"{method} (paper)", "Average", split, metric)] = Cell(
                float(numbers.mean()), std=float(numbers.std(ddof=0))
            )
    return cells


def overview_table(
    frame: pd.DataFrame,
    *,
    suite: str | None = None,
    methods: Sequence[str] | None = None,
    metrics: Sequence[str] = ("psnr", "ssim", "lpips"),
    splits: Sequence[str] = ("train", "test"),
    seeds: str = "mean",
    published: bool = False,
) -> Table:
    """Per-split averages over the suite's scenes (mean ± std over scenes), FPS, training time,
    device.

    ``published=True`` appends the paper's rows for the suite (`published_overview_cells`), never
    ranked.
    """
    selected = select_runs(frame, suite, methods)
    suite = suite or single_suite(selected)
    run_cells = RunCells(selected, seeds)
    scenes, scene_note = expected_scenes(suite, list(selected["scene"]))
    cells = {}
    for row in run_cells.rows:
        for split in splits:
            for metric in metrics:
                cells[(row, "Average", split, metric)] = run_cells.average(
                    row, scenes, split, metric, with_std=True
                )
        fps = run_cells.average(row, scenes, "-", "fps", with_std=True)
        fps.decimals = 1
        cells[(row, "Average", "-", "fps")] = fps
        time = run_cells.average(row, scenes, "-", "train_time")
        cells[(row, "Average", "-", "train_time")] = (
            Cell(_hours(time.number), marks=time.marks) if time.number is not None else time
        )
        devices = sorted(set(run_cells.frame[run_cells.frame["row"] == row]["device"]) - {""})
        cells[(row, "Average", "-", "gpu")] = Cell(", ".join(devices) or None)
    rows = list(run_cells.rows)
    if published:
        paper_cells = published_overview_cells(suite, metrics, splits)
        cells.update(paper_cells)
        rows += list(dict.fromkeys(key[0] for key in paper_cells))
        if paper_cells:
            source = (
                "as printed in Table 1(c)"
                if suite == "sssgs"
                else "mean ± std over the scenes of the paper's per-scene table"
            )
            notes_before = [f"(paper) rows: SSD-GS (ICLR 2026), {source}; never ranked."]
        else:
            notes_before = [f"--published: the paper reports no {suite} overview."]
    else:
        notes_before = []
    table = overview_layout(
        CellLookup(cells),
        rows,
        splits,
        metrics,
        name=f"tab:{suite}-overview",
        caption=(
            f"Averages over the {len(scenes)} scenes of the {suite} suite "
            "(mean ± std over scenes; training time is the mean per scene)."
            if len(scenes) > 1
            else f"Results on the one scene of the {suite} suite ({scenes[0]})."
        ),
        protocol=_protocol_line(run_cells, suite, seeds),
        extras=(("fps", "FPS", "-"), ("train_time", "Train T.", "-"), ("gpu", "Device", "-")),
        rank_sets={row: ("all" if row in run_cells.rows else None) for row in rows},
    )
    table.footnotes += notes_before + ([scene_note] if scene_note else []) + run_cells.notes.lines()
    return table


def significance_mark(values: Sequence[float], reference: Sequence[float]) -> str | None:
    """ "s" when |mean(values) − mean(reference)| > `SIGNIFICANCE_FACTOR` × pooled sample std, else
    "n".

    The pooled std is sqrt((s_a² + s_b²) / 2) of the two sample stds (ddof=1); None when either side
    has fewer than two seeds (no spread to compare with).
    """
    if len(values) < 2 or len(reference) < 2:
        return None
    pooled = math.sqrt((statistics.variance(values) + statistics.variance(reference)) / 2)
    difference = abs(statistics.fmean(values) - statistics.fmean(reference))
    return "s" if difference > SIGNIFICANCE_FACTOR * pooled else "n"


def _noise_marks(
    run_cells: RunCells, row: str, reference: str, scenes: Sequence[str], split: str, metric: str
) -> tuple[str, ...]:
    """The footnote mark ("s" or "n", `significance_mark`) of ``row`` against ``reference`` on the
    per-seed values over ``scenes`` (their per-seed averages for several); none without seed
    spread."""
    mark = significance_mark(
        list(run_cells.seed_values(row, scenes, split, metric).values()),
        list(run_cells.seed_values(reference, scenes, split, metric).values()),
    )
    return run_cells.notes.mark(mark) if mark else ()


def _mark_significance(
    cells: dict,
    run_cells: RunCells,
    rows: Sequence[str],
    sets: Mapping[str, str],
    reference_variants: Mapping[str, str],
    columns: Sequence[Sequence[str]],
    splits: Sequence[str],
    metrics: Sequence[str],
) -> None:
    """Append "s"/"n" to each ablation cell against its grid's reference
    (no mark without seed spread).

    ``sets`` maps each row to its grid, ``reference_variants`` each grid to its reference variant.
    ``columns`` maps each printed column (a scene or "Average") to the scenes it averages, so an
    Average cell is tested on the per-seed averages over scenes.
    """
    references = {
        sets[row]: row
        for row in rows
        if run_cells.source[row][1] == reference_variants.get(sets[row])
    }
    for row in rows:
        reference = references.get(sets[row])
        if reference is None or reference == row:
            continue
        for column, scenes in columns:
            for split in splits:
                for metric in metrics:
                    cell = cells[(row, column, split, metric)]
                    if cell.number is not None:
                        marks = _noise_marks(run_cells, row, reference, scenes, split, metric)
                        cells[(row, column, split, metric)] = replace(
                            cell, marks=(*cell.marks, *marks)
                        )


def ablation_table(
    frame: pd.DataFrame,
    *,
    suite: str | None = None,
    method: str = "ssdgs",
    metrics: Sequence[str] = ("psnr", "ssim", "lpips"),
    splits: Sequence[str] = ("train", "test"),
    seeds: str = "mean",
    published: bool = False,
) -> Table:
    """The runs of ``method``'s ablation grids as rows (SSD-GS: compositions A–F, schedules H–K):
    Table 2 for one scene, the appendix layout for several. Grids come in alphabetical order, a rule
    before each but the first, variants sorted within a grid.

    Cells are mean ± sample std over seeds (an Average: the std of the per-seed averages over
    scenes); with two or more seeds on both sides each cell is marked "s" or "n" by
    `significance_mark` against its grid's reference variant. Grid and reference are what each
    job.json records (`collect`).
    """
    selected = frame[(frame["method"] == method) & (frame["ablation_grid"] != "")]
    if suite is not None:
        selected = selected[selected["suite"] == suite]
    if selected.empty:
        raise ReportError(
            f"no ablation runs of '{method}' found (no job of an ablation grid); run one with "
            f"olatbench run --method {method} --ablation GRID --suite SUITE (olatbench methods "
            f"show {method} lists its grids)"
        )
    selected = selected.sort_values(["ablation_grid", "variant"], kind="stable")
    run_cells = RunCells(selected, seeds, paper_variants=True)
    rows = list(run_cells.rows)
    grid_of = dict(
        zip(
            zip(selected["method"], selected["variant"], strict=True),
            selected["ablation_grid"],
            strict=True,
        )
    )
    sets = {row: grid_of[run_cells.source[row]] for row in rows}
    reference_variants = dict(
        zip(selected["ablation_grid"], selected["ablation_reference"], strict=True)
    )
    scenes = list(dict.fromkeys(selected["scene"]))
    suites = sorted(set(selected["suite"]))
    protocol = _protocol_line(run_cells, ", ".join(suites), seeds, seed_std=True)
    grid_starts = [row for previous, row in itertools.pairwise(rows) if sets[row] != sets[previous]]
    cells = {}
    for row in rows:
        for scene in scenes:
            for split in splits:
                for metric in metrics:
                    cells[(row, scene, split, metric)] = run_cells.cell(
                        row, scene, split, metric, with_std=True
                    )
    columns = [(scene, [scene]) for scene in scenes]
    if len(scenes) > 1:
        for row in rows:
            for split in splits:
                for metric in metrics:
                    average = run_cells.average(row, scenes, split, metric)
                    per_seed = list(run_cells.seed_values(row, scenes, split, metric).values())
                    # spread of the per-seed averages
                    if average.number is not None and len(per_seed) > 1:
                        average = replace(average, std=statistics.stdev(per_seed))
                    cells[(row, "Average", split, metric)] = average
        columns.append(("Average", scenes))
    _mark_significance(cells, run_cells, rows, sets, reference_variants, columns, splits, metrics)
    if len(scenes) == 1:
        scene = scenes[0]
        if published:
            rows = _add_published(
                cells, rows, run_cells, suites[0], [(scene, sp) for sp in splits], metrics, sets
            )
        table = metric_columns_layout(
            CellLookup(cells),
            rows,
            scene,
            splits,
            metrics,
            name="tab:ablation",
            caption=f"Ablation study on {scene}.",
            protocol=protocol,
            rank_sets=sets,
            rule_before=[rows.index(r) for r in grid_starts],
        )
    else:
        if published:
            scene_suites = dict(zip(selected["scene"], selected["suite"], strict=True))
            rows = _add_published(
                cells,
                rows,
                run_cells,
                scene_suites,
                [(scene, sp) for scene in [*scenes, "Average"] for sp in splits],
                metrics,
                sets,
            )
        table = split_rows_layout(
            CellLookup(cells),
            rows,
            [*scenes, "Average"],
            splits,
            metrics,
            name="tab:ablation-scenes",
            caption="Ablation study over scenes.",
            protocol=protocol,
            rank_sets=sets,
            rule_before_rows=grid_starts,
        )
    table.footnotes += run_cells.notes.lines()
    return table
