"""Reports from a tiny folder of results.json files (schema v2) written here: tables, footnotes,
CLI, LaTeX."""

from __future__ import annotations

import csv as csv_module
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from waiting import BACKSTOP_SECONDS

from olatbench.bench.results import read_results, write_results
from olatbench.cli import main
from olatbench.reports.collect import COLUMNS, ResultsWarning, collect
from olatbench.reports.latex import to_latex
from olatbench.reports.output import render_tables
from olatbench.reports.paper import paper_table
from olatbench.reports.published import PAPER_TABLES
from olatbench.reports.ranking import rank_table
from olatbench.reports.runs_tables import ReportError, ablation_table, overview_table, scene_table

SCENES = ("diffuse_shadow", "aniso_metal", "translucent")  # the mini suite, in its order


def write_run(
    root: Path,
    method: str,
    variant: str,
    suite: str,
    scene: str,
    seed: int,
    metrics: dict[str, dict[str, float | None]] | None = None,
    status: str = "done",
    fps: float = 50.0,
    seconds: float = 1800.0,
    device: str = "cpu",
    config: dict | None = None,
    data: str = "x",
    resolution: list[int] | None = None,
) -> Path:
    """One job's results.json in the runner's folder layout."""
    folder = root / suite / method / variant / scene / f"seed{seed}"
    failed = status == "failed"
    data = {
        "schema_version": 2,
        "kind": "run",
        "status": status,
        "job": {
            "id": f"{method}-{variant}-{scene}-{seed}",
            "method": method,
            "variant": variant,
            "suite": suite,
            "scene": scene,
            "seed": seed,
            "config": config or {"iterations": 10},
            **({} if resolution is None else {"resolution": resolution}),
        },
        "protocol": {"id": "olatbench-v1", "version": 1},
        "metrics": {}
        if failed
        else {split: {"mean": mean, "per_image": {}} for split, mean in metrics.items()},
        "timing": {
            "train_seconds": None if failed else seconds,
            "render_fps": None if failed else fps,
        },
        "resources": {"device": device, "peak_rss_mb": 100.0, "cuda_peak_mb": None},
        "model": {"iterations": 10, "num_gaussians": None if failed else 1000},
        "versions": {"olatbench": "0.1.0"},
        "hashes": {"data_manifest": data, "config": "y", "code": "z"},
        "error": {"type": "RuntimeError", "message": "out of memory"} if failed else None,
    }
    return write_results(folder / "results.json", data)


def metric_values(
    psnr: float, ssim: float = 0.9, lpips: float | None = 0.1
) -> dict[str, dict[str, float | None]]:
    return {
        "train": {"psnr": psnr + 1.0, "ssim": ssim, "lpips": lpips},
        "test": {"psnr": psnr, "ssim": ssim - 0.01, "lpips": lpips},
    }


def make_tiny_runs(root: Path) -> Path:
    """ssdgs (2 seeds, one failed), gs3 (LPIPS missing in one scene), rng (one failed, one missing
    scene)."""
    for index, scene in enumerate(SCENES):
        write_run(root, "ssdgs", "mini", "mini", scene, 0, metric_values(30.0 + index))
        if scene == "translucent":
            write_run(root, "ssdgs", "mini", "mini", scene, 1, status="failed")
        else:
            write_run(root, "ssdgs", "mini", "mini", scene, 1, metric_values(31.0 + index))
        lpips = None if scene == "aniso_metal" else 0.05
        write_run(
            root,
            "gs3",
            "default",
            "mini",
            scene,
            0,
            metric_values(29.0 + 2 * index, 0.95, lpips),
            fps=120.0,
            seconds=600.0 * (index + 1),
            device="cuda:0 (RTX 3090)",
        )
    write_run(root, "rng", "default", "mini", "diffuse_shadow", 0, metric_values(25.0))
    write_run(root, "rng", "default", "mini", "aniso_metal", 0, status="failed")
    return root


@pytest.fixture()
def tiny_runs(tmp_path: Path) -> Path:
    return make_tiny_runs(tmp_path / "runs")


def test_collect_long_form(tiny_runs):
    frame = collect(tiny_runs)
    assert list(frame.columns) == list(COLUMNS)
    assert len(frame[frame["status"] == "failed"]) == 2
    psnr = frame[
        (frame["method"] == "ssdgs")
        & (frame["scene"] == "aniso_metal")
        & (frame["split"] == "test")
        & (frame["metric"] == "psnr")
    ]
    assert sorted(psnr["value"]) == [31.0, 32.0]
    assert set(frame["protocol"]) == {"olatbench-v1 v1"}
    fps = frame[(frame["method"] == "gs3") & (frame["metric"] == "fps")]
    assert list(fps["value"]) == [120.0] * 3 and set(fps["split"]) == {"-"}


def test_unknown_schema_version_names_the_file(tmp_path):
    path = tmp_path / "runs" / "results.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"schema_version": 99, "status": "done"}))
    # a file that cannot be read is named and skipped, not the end of the report
    unreadable: list[str] = []
    assert collect(tmp_path / "runs", unreadable).empty
    assert len(unreadable) == 1 and re.search(
        r"results\.json: schema_version 99 is not supported", unreadable[0]
    )
    with pytest.warns(ResultsWarning, match="schema_version 99"):
        collect(tmp_path / "runs")
    result = CliRunner().invoke(main, ["report", str(tmp_path / "runs")])
    assert (
        result.exit_code == 1
        and "schema_version 99" in result.output
        and "Traceback" not in result.output
    )


def test_schema_v1_files_are_read_and_evaluate_files_give_no_rows(tmp_path):
    """A results.json written before schema 2 (no kind, hardware, files, timestamps) still reports;
    a file written by `olatbench evaluate` below the runs folder names no job and adds no rows."""
    v1 = {
        "schema_version": 1,
        "status": "done",
        "job": {
            "id": "abc",
            "method": "ssdgs",
            "variant": "default",
            "suite": "mini",
            "scene": "translucent",
            "seed": 0,
            "config": {},
        },
        "protocol": {"id": "olatbench-v1", "version": 1},
        "metrics": {"test": {"mean": {"psnr": 25.0, "ssim": 0.9, "lpips": 0.1}, "per_image": {}}},
        "timing": {"train_seconds": 10.0, "render_fps": 5.0},
        "resources": {"device": "cpu", "peak_rss_mb": 100.0, "cuda_peak_mb": None},
        "model": {"iterations": 10, "num_gaussians": 5},
        "versions": {"olatbench": "0.1.0"},
        "hashes": {"data_manifest": "x", "config": "y", "code": "z"},
        "evaluation": {"test_time_refinement": None},
        "error": None,
    }
    old = (
        tmp_path / "runs" / "mini" / "ssdgs" / "default" / "translucent" / "seed0" / "results.json"
    )
    old.parent.mkdir(parents=True)
    old.write_text(json.dumps(v1))
    upgraded = read_results(old)
    assert (
        upgraded["schema_version"] == 2 and upgraded["kind"] == "run" and "hardware" not in upgraded
    )
    assert upgraded["metrics"] == v1["metrics"] and upgraded["job"] == v1["job"]
    evaluated = {key: value for key, value in upgraded.items() if key not in ("job", "model")}
    write_results(
        tmp_path / "runs" / "scored" / "results.json",
        {**evaluated, "kind": "evaluate", "job": None},
    )
    frame = collect(tmp_path / "runs")
    psnr = frame[(frame["metric"] == "psnr") & (frame["split"] == "test")]
    assert list(psnr["value"]) == [25.0] and list(psnr["scene"]) == ["translucent"]


def test_scene_table_means_marks_and_footnotes(tiny_runs):
    table = rank_table(scene_table(collect(tiny_runs), average=True))
    assert table.columns[:2] == ["diffuse_shadow/Train", "diffuse_shadow/Test"]
    # mean over two seeds
    assert table.cell("PSNR ↑", ("ssdgs/mini",), "aniso_metal/Test").number == pytest.approx(31.5)
    # one seed failed: the finished seed only, marked "c"
    partial = table.cell("PSNR ↑", ("ssdgs/mini",), "translucent/Test")
    assert partial.number == pytest.approx(32.0) and partial.marks == ("c",)
    # failed run "a", missing run "b", average over incomplete scenes "d", metric not computed "e"
    assert table.cell("PSNR ↑", ("rng",), "aniso_metal/Test").marks == ("a",)
    assert table.cell("PSNR ↑", ("rng",), "translucent/Test").marks == ("b",)
    assert table.cell("PSNR ↑", ("rng",), "Average/Test").text() == "—"
    assert table.cell("PSNR ↑", ("rng",), "Average/Test").marks == ("d",)
    assert table.cell("LPIPS ↓", ("gs3",), "aniso_metal/Test").marks == ("e",)
    assert table.cell("LPIPS ↓", ("gs3",), "Average/Test").number is None
    # the average is the plain mean of the per-scene cells
    ssdgs = [table.cell("PSNR ↑", ("ssdgs/mini",), f"{s}/Test").number for s in SCENES]
    assert table.cell("PSNR ↑", ("ssdgs/mini",), "Average/Test").number == pytest.approx(
        np.mean(ssdgs)
    )
    # includes the partial seed mean
    assert table.cell("PSNR ↑", ("ssdgs/mini",), "Average/Test").marks == ("c",)
    assert table.cell("PSNR ↑", ("gs3",), "Average/Test").marks == ()
    # ranking: ssdgs 30.5 > gs3 29 > rng 25 on diffuse_shadow Test; lower-is-better LPIPS: gs3 0.05
    # best
    assert table.cell("PSNR ↑", ("ssdgs/mini",), "diffuse_shadow/Test").rank == 1
    assert table.cell("PSNR ↑", ("gs3",), "diffuse_shadow/Test").rank == 2
    assert table.cell("PSNR ↑", ("rng",), "diffuse_shadow/Test").rank is None
    assert table.cell("LPIPS ↓", ("gs3",), "diffuse_shadow/Test").rank == 1
    assert table.protocol.startswith("olatbench-v1 v1; suite mini")
    notes = "\n".join(table.footnotes)
    for letter in "abcde":
        assert f"{letter}: " in notes
    assert "Failed: rng on aniso_metal, seed 0 — RuntimeError: out of memory" in notes


def test_seeds_all_gives_one_row_per_seed(tiny_runs):
    table = scene_table(collect(tiny_runs), methods=["ssdgs"], seeds="all")
    assert [row.labels[0] for row in table.blocks[0].rows] == [
        "ssdgs/mini seed0",
        "ssdgs/mini seed1",
    ]
    assert table.cell("PSNR ↑", ("ssdgs/mini seed1",), "translucent/Test").marks == ("a",)


def test_selection_errors_are_clear(tiny_runs):
    frame = collect(tiny_runs)
    with pytest.raises(ReportError, match="the runs hold suites mini"):
        scene_table(frame, suite="gs3")
    with pytest.raises(ReportError, match="no ablation runs"):
        ablation_table(frame)


def test_overview_mean_std_fps_time_device(tiny_runs):
    table = overview_table(collect(tiny_runs), methods=["gs3"])
    psnr = table.cell(None, ("gs3",), "Test (Average)/PSNR ↑")
    expected = [29.0, 31.0, 33.0]
    assert psnr.number == pytest.approx(np.mean(expected)) and psnr.std == pytest.approx(
        np.std(expected)
    )
    assert table.cell(None, ("gs3",), "FPS").text() == "120.0 ± 0.0"
    assert table.cell(None, ("gs3",), "Train T.").text() == "20.0 min"  # mean of 10, 20, 30 minutes
    assert table.cell(None, ("gs3",), "Device").text() == "cuda:0 (RTX 3090)"
    lpips = table.cell(None, ("gs3",), "Test (Average)/LPIPS ↓")
    assert lpips.value is None and lpips.marks == ("d",)


def test_published_beside_runs_adds_paper_and_delta_rows(tmp_path):
    root = tmp_path / "runs"
    write_run(root, "ssdgs", "nrhints", "nrhints", "Cat", 0, metric_values(28.0, 0.9, 0.12))
    write_run(root, "mymethod", "default", "nrhints", "Cat", 0, metric_values(20.0))
    table = rank_table(scene_table(collect(root), published=True))
    labels = [row.labels[0] for row in table.blocks[0].rows]
    assert labels == ["mymethod", "ssdgs/nrhints", "Ours (paper)", "Δ ssdgs/nrhints − paper"]
    assert table.cell("PSNR ↑", ("Ours (paper)",), "Cat/Test").number == 27.6844
    delta = table.cell("PSNR ↑", ("Δ ssdgs/nrhints − paper",), "Cat/Test")
    assert delta.number == pytest.approx(28.0 - 27.6844) and delta.text() == "+0.3156"
    # paper rows are never ranked
    assert table.cell("PSNR ↑", ("Ours (paper)",), "Cat/Test").rank is None
    assert table.cell("PSNR ↑", ("Δ ssdgs/nrhints − paper",), "Fish/Test").value is None
    assert any(note.startswith("(paper) rows") for note in table.footnotes)


def test_overview_with_published_rows(tmp_path):
    root = tmp_path / "runs"
    for index, scene in enumerate(("Bunny", "Candle", "Dragon", "Soap", "Statue")):
        write_run(root, "ssdgs", "sssgs", "sssgs", scene, 0, metric_values(36.0 + index))
    table = rank_table(overview_table(collect(root), published=True))
    labels = [row.labels[0] for row in table.blocks[0].rows]
    assert labels == [
        "ssdgs/sssgs",
        "KiloOSF (paper)",
        "SSS-GS (paper)",
        "Ours (w/o Opt) (paper)",
        "Ours (w/ Opt) (paper)",
    ]
    assert table.cell(None, ("SSS-GS (paper)",), "Test (Average)/PSNR ↑").text() == "35.01 ± 1.01"
    assert table.cell(None, ("KiloOSF (paper)",), "Train T.").text() == ">20 h"
    assert table.cell(None, ("Ours (w/ Opt) (paper)",), "Test (Average)/PSNR ↑").rank is None
    assert table.cell(None, ("ssdgs/sssgs",), "Test (Average)/PSNR ↑").number == pytest.approx(38.0)
    nrhints = tmp_path / "nrhints"
    write_run(nrhints, "ssdgs", "nrhints", "nrhints", "Cat", 0, metric_values(28.0))
    derived = overview_table(collect(nrhints), published=True, metrics=["psnr"], splits=["test"])
    ours = derived.cell(None, ("Ours (paper)",), "Test (Average)/PSNR ↑")
    # Table 1(a), Ours, Test
    paper = [27.6844, 34.6472, 37.4702, 31.1646, 30.7349, 31.9298, 31.1213]
    assert ours.number == pytest.approx(np.mean(paper)) and ours.std == pytest.approx(np.std(paper))


def test_ablation_tables_from_runs(tmp_path):
    root = tmp_path / "runs"
    for variant, psnr in (
        ("ablation-A", 20.0),
        ("ablation-D", 33.0),
        ("schedule-H", 32.0),
        ("schedule-I", 33.0),
    ):
        write_run(root, "ssdgs", variant, "nrhints", "Pixiu", 0, metric_values(psnr))
    table = rank_table(ablation_table(collect(root), published=True))
    labels = [row.labels[0] for row in table.blocks[0].rows]
    assert labels[0] == "A: Diff" and "H: Joint" in labels and "A: Diff (paper)" in labels
    assert table.cell(None, ("A: Diff (paper)",), "Train Set/PSNR ↑").number == 20.2869
    assert table.cell(None, ("D: Full (Ours)",), "Test Set/PSNR ↑").rank == 1
    # ranked within schedules
    assert table.cell(None, ("I: Prog. Phys (Ours)",), "Test Set/PSNR ↑").rank == 1
    assert table.cell(None, ("A: Diff",), "Test Set/PSNR ↑").rank == 2
    for variant, psnr in (("ablation-A", 21.0), ("ablation-D", 31.0)):
        write_run(root, "ssdgs", variant, "gs3", "Lego", 0, metric_values(psnr))
    grid = rank_table(ablation_table(collect(root), published=True))
    assert grid.label_names == ("Method", "Split")
    # a GS3 scene
    assert grid.cell("PSNR ↑", ("A: Diff (paper)", "Train"), "Lego").number == 20.6157
    # an NRHints scene
    assert grid.cell("PSNR ↑", ("A: Diff (paper)", "Test"), "Pixiu").number == 20.1878
    assert grid.cell("PSNR ↑", ("A: Diff (paper)", "Test"), "Average").number == pytest.approx(
        (20.1878 + 17.6430) / 2
    )
    assert grid.cell("PSNR ↑", ("A: Diff", "Test"), "Average").number == pytest.approx(20.5)
    assert grid.cell("PSNR ↑", ("H: Joint", "Test"), "Average").marks == ("d",)  # no Lego run


def test_ablation_cells_carry_seed_spread_and_significance(tmp_path):
    """Mean ± sample std over seeds; "s" only where |Δ| to the full model exceeds 2 × pooled std."""
    root = tmp_path / "runs"
    # Δ = 5, std 0.2: real
    psnrs = {
        "ablation-D": (30.0, 30.2, 29.8),
        "ablation-A": (25.0, 25.2, 24.8),
        # Δ = 0.1, std 0.4: noise
        "ablation-E": (29.9, 30.3, 29.5),
        "schedule-I": (30.0, 30.2, 29.8),
        "schedule-H": (29.0, 29.2, 28.8),
    }  # Δ = 1.0 > 2 × 0.2: real
    for variant, values in psnrs.items():
        for seed, psnr in enumerate(values):
            write_run(root, "ssdgs", variant, "nrhints", "Pixiu", seed, metric_values(psnr))
    table = ablation_table(collect(root), metrics=["psnr"], splits=["test"])
    full = table.cell(None, ("D: Full (Ours)",), "Test Set/PSNR ↑")
    assert full.number == pytest.approx(30.0) and full.std == pytest.approx(
        np.std((30.0, 30.2, 29.8), ddof=1)
    )
    assert full.marks == ()  # the reference itself is not tested
    assert table.cell(None, ("A: Diff",), "Test Set/PSNR ↑").marks == ("s",)
    assert table.cell(None, ("E: Full - S",), "Test Set/PSNR ↑").marks == ("n",)
    assert table.cell(None, ("H: Joint",), "Test Set/PSNR ↑").marks == ("s",)  # against I, not D
    assert any("seed noise" in line for line in table.footnotes)
    # a second scene: the Average is tested on per-seed averages
    for variant in ("ablation-D", "ablation-A"):
        for seed, psnr in enumerate((20.0, 20.1, 19.9)):
            write_run(root, "ssdgs", variant, "gs3", "Lego", seed, metric_values(psnr))
    grid = ablation_table(collect(root), metrics=["psnr"], splits=["test"])
    average = grid.cell("PSNR ↑", ("A: Diff", "Test"), "Average")
    assert average.number == pytest.approx((25.0 + 20.0) / 2) and average.marks == ("s",)
    per_seed = [(25.0 + 20.0) / 2, (25.2 + 20.1) / 2, (24.8 + 19.9) / 2]
    assert average.std == pytest.approx(np.std(per_seed, ddof=1))


def test_ablation_single_seed_has_no_significance_mark(tmp_path):
    root = tmp_path / "runs"
    for variant, psnr in (("ablation-A", 20.0), ("ablation-D", 33.0)):
        write_run(root, "ssdgs", variant, "nrhints", "Pixiu", 0, metric_values(psnr))
    table = ablation_table(collect(root), metrics=["psnr"], splits=["test"])
    cell = table.cell(None, ("A: Diff",), "Test Set/PSNR ↑")
    assert cell.marks == () and cell.std is None


def latex_balance_problems(text: str) -> list[str]:
    """Unbalanced braces, environments or inline math, and tabular rows with the wrong number of
    cells."""
    problems = []
    depth = 0
    for char in re.sub(r"\\[{}$&%#_]", "", text):
        depth += {"{": 1, "}": -1}.get(char, 0)
        if depth < 0:
            problems.append("a '}' closes nothing")
            depth = 0
    if depth:
        problems.append(f"{depth} unclosed '{{'")
    stack = []
    for kind, name in re.findall(r"\\(begin|end)\{([^}]*)\}", text):
        if kind == "begin":
            stack.append(name)
        elif not stack or stack.pop() != name:
            problems.append(f"\\end{{{name}}} does not match")
    problems += [f"\\begin{{{name}}} not closed" for name in stack]
    for line in text.splitlines():
        if re.sub(r"\\\$", "", line).count("$") % 2:
            problems.append(f"odd number of $ in: {line[:60]}")
    for match in re.finditer(r"\\begin\{tabular\}\{([^}]*)\}(.*?)\\end\{tabular\}", text, re.S):
        columns = len(re.sub(r"[^lcr]", "", match.group(1)))
        for row in match.group(2).split("\\\\"):
            if "&" in row and "\\multicolumn" not in row:
                cells = len(re.sub(r"\\&", "", row).split("&"))
                if cells != columns:
                    problems.append(f"row with {cells} cells in a {columns}-column tabular")
    return problems


def test_latex_balance_checker_catches_errors():
    assert latex_balance_problems(r"\begin{table}{x}\end{table}") == []
    assert latex_balance_problems(r"\begin{table}{x\end{tabular}")
    assert latex_balance_problems(r"\begin{tabular}{cc} a & b & c \\ \end{tabular}")


def test_latex_output_is_balanced(tiny_runs):
    tables = [paper_table(name) for name in PAPER_TABLES]
    tables.append(rank_table(scene_table(collect(tiny_runs), average=True)))
    for table in tables:
        for rules in ("hline", "booktabs"):
            text = to_latex(table, rules=rules, standalone=True)
            assert latex_balance_problems(text) == [], table.name
            assert text.startswith("\\documentclass") and text.rstrip().endswith("\\end{document}")


def _pdflatex(
    folder: Path, name: str, text: str, env: dict | None = None
) -> subprocess.CompletedProcess:
    (folder / name).write_text(text)
    return subprocess.run(
        ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", name],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
        env=env,
    )


def test_standalone_latex_needs_only_texlive_latex_recommended_and_keeps_natural_width(tiny_runs):
    """The LaTeX text itself (no TeX needed): --standalone loaded multirow and diagbox, which
    Debian's texlive-latex-recommended lacks, and scaled every table to \\linewidth (a huge table
    under a small caption)."""
    from olatbench.reports.latex import PAPER_PACKAGES, PORTABLE_PACKAGES

    runner = CliRunner()
    standalone = runner.invoke(
        main, ["report", str(tiny_runs), "--format", "latex", "--standalone"]
    ).output
    packages = re.findall(r"\\usepackage(?:\[[^]]*\])?\{([^}]*)\}", standalone)
    assert set(packages) == {"geometry", "xcolor", "colortbl", "booktabs", "graphicx"}
    assert {package.split("{")[1].rstrip("}") for package in PORTABLE_PACKAGES} <= set(packages)
    assert "\\multirow" not in standalone and "\\diagbox" not in standalone
    assert "\\resizebox" not in standalone and latex_balance_problems(standalone) == []
    fitted = runner.invoke(
        main, ["report", str(tiny_runs), "--format", "latex", "--standalone", "--fit"]
    ).output
    # shrinks, never enlarges
    assert "\\resizebox{\\ifdim\\width>\\linewidth\\linewidth\\else\\width\\fi}{!}" in fitted
    paper = runner.invoke(main, ["report", str(tiny_runs), "--format", "latex"]).output
    assert (
        paper.startswith("% Needs in the preamble:")
        and "texlive-latex-extra" in paper.splitlines()[1]
    )
    assert all(f"\\usepackage{package}" in paper.splitlines()[0] for package in PAPER_PACKAGES)
    assert "\\diagbox" in paper  # the paper's flavour keeps the paper's corner


@pytest.mark.skipif(
    shutil.which("pdflatex") is None,
    reason="pdflatex is not installed (apt-get install texlive-latex-recommended); the LaTeX-text "
    "test stands in for it",
)
def test_latex_compiles_with_pdflatex(tmp_path, tiny_runs):
    write_run(tiny_runs, "ssdgs", "nrhints", "nrhints", "Cat", 0, metric_values(28.0))
    tables = [paper_table(name) for name in PAPER_TABLES]
    tables.append(
        rank_table(scene_table(collect(tiny_runs), suite="nrhints", average=True, published=True))
    )
    for rules in ("hline", "booktabs"):
        for fit in (False, True):
            name = f"tables_{rules}_{fit}.tex"
            run = _pdflatex(
                tmp_path,
                name,
                render_tables(tables, "latex", standalone=True, rules=rules, fit=fit),
            )
            assert run.returncode == 0, run.stdout[-2000:]
            assert (tmp_path / name.replace(".tex", ".pdf")).stat().st_size > 1000
    extras = subprocess.run(
        ["kpsewhich", "multirow.sty", "diagbox.sty"], capture_output=True, text=True
    ).stdout
    # the paper's flavour, in a document that loads what its first line names
    if len(extras.split()) == 2:
        paper = render_tables(tables, "latex")
        preamble = (
            paper.splitlines()[0].removeprefix("% Needs in the preamble: ").replace(", ", "\n")
        )
        run = _pdflatex(
            tmp_path,
            "paper.tex",
            f"\\documentclass{{article}}\n{preamble}\n\\begin{{document}}\n{paper}"
            "\\end{document}\n",
        )
        assert run.returncode == 0, run.stdout[-2000:]


def test_cli_report_formats(tiny_runs, tmp_path):
    runner = CliRunner()
    markdown = runner.invoke(main, ["report", str(tiny_runs), "--suite", "mini", "--average"])
    assert markdown.exit_code == 0, markdown.output
    assert (
        "| ssdgs/mini | **31.5000 ± 0.7071** |" in markdown.output
        and "Protocol: olatbench-v1 v1" in markdown.output
    )
    assert (
        "mean ± sample std over 1–2 seeds per cell (a one-seed cell has no ±) — seeds per cell: "
        "gs3 1; rng 1; "
        # two seeds: sample std (ddof=1) shown
        "ssdgs/mini 2 (translucent 1)"
    ) in markdown.output
    out = tmp_path / "t.csv"
    csv = runner.invoke(
        main, ["report", str(tiny_runs), "--metrics", "psnr", "--splits", "test", "-o", str(out)]
    )
    assert csv.exit_code == 0, csv.output
    # tidy: one row per job × split × metric
    rows = list(csv_module.DictReader(out.read_text().splitlines()))
    psnr = [row for row in rows if row["metric"] == "psnr"]
    assert {row["split"] for row in psnr} == {"test"}
    ssdgs = sorted(
        float(row["value"])
        for row in psnr
        if row["method"] == "ssdgs" and row["scene"] == "aniso_metal"
    )
    assert ssdgs == [31.0, 32.0]  # every seed, full precision, no display marks
    assert {row["protocol_id"] for row in rows} == {"olatbench-v1"} and {
        row["protocol_version"] for row in rows
    } == {"1"}
    assert len([row for row in rows if row["status"] == "failed"]) == 2
    gs3_lpips = runner.invoke(
        main, ["report", str(tiny_runs), "--metrics", "lpips", "--format", "csv"]
    ).output
    assert ",lpips,,done," in gs3_lpips  # a metric the run did not compute: an empty field
    latex = runner.invoke(
        main,
        [
            "report",
            str(tiny_runs),
            "--format",
            "latex",
            "--standalone",
            "--booktabs",
            "--colours",
            "0.8,1,0.8;0.9,1,0.9",
        ],
    )
    assert latex.exit_code == 0 and latex_balance_problems(latex.output) == []
    assert "\\cellcolor[rgb]{0.8,1,0.8}" in latex.output and "\\toprule" in latex.output
    overview = runner.invoke(
        main, ["report", str(tiny_runs), "--layout", "overview", "--format", "markdown"]
    )
    assert overview.exit_code == 0 and "Train T." in overview.output
    bad = runner.invoke(main, ["report", str(tiny_runs), "--colours", "red"])
    assert bad.exit_code == 2 and "three comma-separated numbers" in bad.output  # a usage error
    nothing = runner.invoke(main, ["report"])
    assert nothing.exit_code == 2 and "--published-only" in nothing.output


def test_cli_published_only(tmp_path):
    out = tmp_path / "paper.tex"
    result = CliRunner().invoke(
        main,
        [
            "report",
            "--published-only",
            "--table",
            "real",
            "--table",
            "ablation",
            "-o",
            str(out),
            "--standalone",
        ],
    )
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert text.count("\\begin{tabular}") == 2 and latex_balance_problems(text) == []
    every = CliRunner().invoke(main, ["report", "--published-only", "--format", "csv"])
    assert every.exit_code == 0 and every.output.startswith(
        "table,method,suite,scene,split,metric,value"
    )
    assert {line.split(",")[0] for line in every.output.splitlines()[1:]} == set(
        PAPER_TABLES.values()
    )


def test_latex_escapes_the_tilde_of_override_labels():
    """Variant labels with overrides hold '~' (``default~use_sss=false``): it must print as a tilde,
    not as ≈ (and never as LaTeX's non-breaking space)."""
    from olatbench.reports.latex import latex_text

    assert latex_text("default~use_sss=false") == r"default\textasciitilde{}use\_sss=false"
    assert latex_text("≈ 2 h") == r"$\approx$ 2 h"


def test_reports_never_average_different_experiments(tmp_path):
    """A 5-step and an 8-step run of one method, variant and scene (the issue's 300/3000-step case,
    in two run folders) are two rows labelled by what differs, each a one-seed mean without ±."""
    write_run(
        tmp_path / "a",
        "ssdgs",
        "default",
        "mini",
        "translucent",
        0,
        metric_values(15.0),
        config={"iterations": 5, "lr": 0.1},
    )
    write_run(
        tmp_path / "b",
        "ssdgs",
        "default",
        "mini",
        "translucent",
        0,
        metric_values(24.0),
        config={"iterations": 8, "lr": 0.1},
    )
    runner = CliRunner()
    for seeds in ("mean", "all"):
        result = runner.invoke(
            main,
            [
                "report",
                str(tmp_path / "a"),
                str(tmp_path / "b"),
                "--metrics",
                "psnr",
                "--splits",
                "test",
                "--seeds",
                seeds,
            ],
        )
        assert result.exit_code == 0, result.output
        suffix = " seed0" if seeds == "all" else ""
        assert f"| ssdgs (iterations=5){suffix} |" in result.output and "15.0000" in result.output
        assert f"| ssdgs (iterations=8){suffix} |" in result.output and "24.0000" in result.output
        # no cell is a spread over the two experiments
        assert "±" not in result.output.split("\n\n", 2)[2]
        assert "19.5" not in result.output  # never their mean
    assert (
        "mean over 1 seed;" in result.output
        or "mean over 1 seed\n"
        in runner.invoke(
            main,
            [
                "report",
                str(tmp_path / "a"),
                str(tmp_path / "b"),
                "--metrics",
                "psnr",
                "--splits",
                "test",
            ],
        ).output
    )


def test_report_rows_split_by_data_and_resolution_and_count_seeds_per_cell(tmp_path):
    runs = tmp_path / "runs"
    for seed in (0, 1):
        write_run(runs, "gs3", "default", "mini", "translucent", seed, metric_values(20.0 + seed))
        write_run(runs, "gs3", "default", "mini", "aniso_metal", seed, metric_values(22.0 + seed))
    write_run(
        runs, "gs3", "default", "mini", "translucent", 2, metric_values(30.0), data="re-rendered"
    )
    frame = collect(runs)
    table = scene_table(frame, metrics=["psnr"], splits=["test"])
    rows = [row.labels[0] for row in table.blocks[0].rows]
    # the seed on other data is not averaged with the first two
    assert rows == ["gs3 (data v1)", "gs3 (data v2)"]
    assert table.cell("PSNR ↑", ("gs3 (data v1)",), "translucent/Test").number == pytest.approx(
        20.5
    )
    second = table.cell("PSNR ↑", ("gs3 (data v2)",), "translucent/Test")
    assert second.number == 30.0 and second.std is None
    assert "1–2 seeds per cell" in table.protocol and "gs3 (data v2) 1" in table.protocol

    other = tmp_path / "other"
    write_run(
        other, "gs3", "default", "mini", "translucent", 0, metric_values(20.0), resolution=[64, 48]
    )
    write_run(
        other, "gs3", "default", "mini", "translucent", 1, metric_values(26.0), resolution=[32, 24]
    )
    labels = [
        row.labels[0]
        for row in scene_table(collect(other), metrics=["psnr"], splits=["test"]).blocks[0].rows
    ]
    assert labels == ["gs3 (resolution=32x24)", "gs3 (resolution=64x48)"] or labels == [
        "gs3 (resolution=64x48)",
        "gs3 (resolution=32x24)",
    ]


def test_report_json_is_every_number_with_its_jobs_identity(tiny_runs):
    result = CliRunner().invoke(
        main, ["report", str(tiny_runs), "--json", "--metrics", "psnr,lpips"]
    )
    assert result.exit_code == 0, result.output
    records = json.loads(result.output)
    metric_rows = [r for r in records if r["split"] not in ("-", "")]
    assert {r["metric"] for r in metric_rows} == {"psnr", "lpips"}
    # metrics × splits × finished jobs (ssdgs 5, gs3 3, rng 1)
    assert len(metric_rows) == 2 * 2 * (3 + 2 + 3 + 1)
    first = next(
        r
        for r in records
        if r["method"] == "ssdgs"
        and r["scene"] == "aniso_metal"
        and r["seed"] == 1
        and r["split"] == "test"
        and r["metric"] == "psnr"
    )
    assert first["value"] == 32.0 and isinstance(first["seed"], int)
    assert first["protocol"] == {"id": "olatbench-v1", "version": 1} and first["config"] == {
        "iterations": 10
    }
    assert first["job_id"] == "ssdgs-mini-aniso_metal-1" and first["variant"] == "mini"
    assert all(isinstance(r["value"], float) or r["value"] is None for r in records)
    missing = [
        r
        for r in metric_rows
        if r["method"] == "gs3" and r["scene"] == "aniso_metal" and r["metric"] == "lpips"
    ]
    assert [r["value"] for r in missing] == [None, None]  # not computed: null, never NaN
    assert {r["metric"] for r in records if r["split"] == "-"} == {
        "fps",
        "train_time",
        "num_gaussians",
    }
    assert [r["error"] for r in records if r["status"] == "failed"] == [
        "RuntimeError: out of memory"
    ] * 2
    published = CliRunner().invoke(
        main, ["report", "--published-only", "--table", "real", "--format", "csv"]
    )
    assert published.exit_code == 0 and published.output.startswith(
        "table,method,suite,scene,split,metric,value"
    )


def write_unfinished(
    root: Path,
    method: str,
    variant: str,
    suite: str,
    scene: str,
    seed: int,
    step: int | None = None,
) -> Path:
    """A job folder the runner planned (job.json) but has not finished: no results.json; a
    checkpoint at ``step``."""
    folder = root / suite / method / variant / scene / f"seed{seed}"
    folder.mkdir(parents=True)
    job = {
        "id": f"{method}-{variant}-{scene}-{seed}",
        "method": method,
        "variant": variant,
        "suite": suite,
        "scene": scene,
        "seed": seed,
        "config": {"iterations": 10},
        "protocol": "olatbench-v1",
        "protocol_version": 1,
        "code": "z",
        "data_manifest": "x",
        "device": "cpu",
    }
    (folder / "job.json").write_text(json.dumps(job))
    if step is not None:
        (folder / "checkpoints").mkdir()
        (folder / "checkpoints" / f"step_{step}.pt").write_bytes(b"")
    return folder


def test_unfinished_jobs_are_named_with_their_cell_not_left_out(tmp_path):
    """A running, an interrupted and a planned job (job.json, no results.json) used to vanish from
    the tables."""
    from olatbench.bench.store import job_lock

    runs = tmp_path / "runs"
    write_run(runs, "ssdgs", "default", "mini", "translucent", 0, metric_values(20.0))
    running = write_unfinished(runs, "ssdgs", "default", "mini", "translucent", 1, step=4)
    write_unfinished(runs, "ssdgs", "default", "mini", "aniso_metal", 0, step=6)
    write_unfinished(runs, "gs3", "default", "mini", "translucent", 0)
    with job_lock(running) as held:  # another process would hold it while training
        assert held
        frame = collect(runs)
        result = CliRunner().invoke(main, ["report", str(runs), "--json", "--metrics", "psnr"])
    table = scene_table(frame, metrics=["psnr"], splits=["test"])
    # seed 1 still running
    assert table.cell("PSNR ↑", ("ssdgs",), "translucent/Test").marks == ("c",)
    assert table.cell("PSNR ↑", ("ssdgs",), "aniso_metal/Test").marks == ("r",)
    assert table.cell("PSNR ↑", ("gs3",), "translucent/Test").marks == ("r",)
    notes = "\n".join(table.footnotes)
    assert "Not finished: ssdgs on translucent, seed 1 — running, step 4 of 10" in notes
    assert "Not finished: ssdgs on aniso_metal, seed 0 — interrupted at step 6 of 10" in notes
    assert "Not finished: gs3 on translucent, seed 0 — planned, not started" in notes
    assert "r: the run has not finished" in notes
    records = json.loads(result.output)
    assert {
        (r["method"], r["scene"], r["seed"], r["status"]) for r in records if r["status"] != "done"
    } == {
        ("ssdgs", "translucent", 1, "running"),
        ("ssdgs", "aniso_metal", 0, "partial"),
        ("gs3", "translucent", 0, "pending"),
    }


def test_a_one_scene_overview_prints_no_spread(tmp_path):
    """One scene has no spread over scenes: the overview printed "± 0.0000" (and "± 0.0" FPS)."""
    write_run(tmp_path, "ssdgs", "default", "myscene", "Pig", 0, metric_values(20.0))
    write_run(tmp_path, "ssdgs", "default", "myscene", "Pig", 1, metric_values(22.0))
    table = overview_table(collect(tmp_path), metrics=["psnr"], splits=["test"])
    assert table.cell(None, ("ssdgs",), "Test (Average)/PSNR ↑").text() == "21.0000"
    assert table.cell(None, ("ssdgs",), "FPS").text() == "50.0"
    assert "±" not in table.caption and "Pig" in table.caption
    markdown = (
        CliRunner()
        .invoke(
            main,
            [
                "report",
                str(tmp_path),
                "--layout",
                "overview",
                "--layout",
                "scenes",
                "--average",
                "--metrics",
                "psnr",
            ],
        )
        .output
    )
    assert "21.0000 ± 1.4142" in markdown  # the scene cell: sample std over the two seeds
    # no spread over one scene, in the overview or the Average column
    assert "± 0.0" not in markdown


def test_versus_adds_a_delta_row_tested_against_seed_noise(tmp_path):
    """`--versus`: "Δ ROW − REF" beneath every other row, the difference of the means marked "s"
    beyond 2 × the pooled std over seeds and "n" within it; an Average tested on per-seed
    averages; a one-seed row unmarked."""
    root = tmp_path / "runs"
    psnrs = {
        "official": {"diffuse_shadow": (20.0, 20.2, 19.8), "aniso_metal": (17.0, 17.4, 16.6)},
        # Δ = +3, std 0.2: beyond; Δ = +0.1, std 0.4: within
        "mini": {"diffuse_shadow": (23.0, 23.2, 22.8), "aniso_metal": (17.1, 17.5, 16.7)},
    }
    for variant, scenes in psnrs.items():
        for scene, values in scenes.items():
            for seed, psnr in enumerate(values):
                write_run(root, "ssdgs", variant, "mini", scene, seed, metric_values(psnr))
    write_run(root, "gs3", "default", "mini", "diffuse_shadow", 0, metric_values(18.0))
    frame = collect(root)
    table = scene_table(frame, metrics=["psnr"], splits=["test"], versus="ssdgs/official")
    labels = [row.labels[0] for row in table.blocks[0].rows]
    assert labels == [
        "gs3",
        "Δ gs3 − ssdgs/official",
        "ssdgs/mini",
        "Δ ssdgs/mini − ssdgs/official",
        "ssdgs/official",
    ]
    delta = "Δ ssdgs/mini − ssdgs/official"
    beyond = table.cell("PSNR ↑", (delta,), "diffuse_shadow/Test")
    assert beyond.number == pytest.approx(3.0) and beyond.marks == ("s",)
    assert beyond.text() == "+3.0000"
    within = table.cell("PSNR ↑", (delta,), "aniso_metal/Test")
    assert within.number == pytest.approx(0.1) and within.marks == ("n",)
    one_seed = table.cell("PSNR ↑", ("Δ gs3 − ssdgs/official",), "diffuse_shadow/Test")
    assert one_seed.number == pytest.approx(-2.0) and one_seed.marks == ()
    assert table.cell("PSNR ↑", (delta,), "diffuse_shadow/Test").rank is None
    # the Average column (every scene needs a value): per-seed averages over the three scenes,
    # 21.70 / 21.93 / 21.47 against 20.67 / 20.90 / 20.43, Δ 1.03 beyond 2 × 0.23
    for variant in psnrs:
        for seed, psnr in enumerate((25.0, 25.1, 24.9)):
            write_run(root, "ssdgs", variant, "mini", "translucent", seed, metric_values(psnr))
    frame = collect(root)
    averaged = scene_table(
        frame,
        methods=["ssdgs"],
        metrics=["psnr"],
        splits=["test"],
        average=True,
        versus="SSDGS/OFFICIAL",
    )
    assert averaged.cell("PSNR ↑", (delta,), "Average/Test").marks == ("s",)
    notes = "\n".join(table.footnotes)
    assert "the row above − ssdgs/official" in notes and "--versus row" in notes


def test_versus_names_one_row_or_says_which(tmp_path):
    root = tmp_path / "runs"
    for variant in ("mini", "official"):
        write_run(root, "ssdgs", variant, "mini", "aniso_metal", 0, metric_values(17.0))
    write_run(root, "gs3", "default", "mini", "aniso_metal", 0, metric_values(15.0))
    frame = collect(root)
    assert scene_table(frame, versus="gs3/default").blocks[0].rows[0].labels == ("gs3",)
    with pytest.raises(ReportError, match=r"matches 2 rows \(ssdgs/mini; ssdgs/official\)"):
        scene_table(frame, versus="ssdgs")
    with pytest.raises(ReportError, match=r"no row 'ssdgs/oficial'.*ssdgs/official"):
        scene_table(frame, versus="ssdgs/oficial")
    with pytest.raises(ReportError, match="not with --published or --seeds all"):
        scene_table(frame, versus="gs3", seeds="all")
    runner = CliRunner()
    for extra in (["--json"], ["--layout", "overview"], ["--published"]):
        result = runner.invoke(main, ["report", str(root), "--versus", "gs3", *extra])
        assert result.exit_code == 2, result.output
    result = runner.invoke(main, ["report", str(root), "--versus", "ssdgs"])
    assert result.exit_code == 2 and "matches 2 rows" in result.output
    result = runner.invoke(main, ["report", str(root), "--versus", "gs3", "--splits", "test"])
    assert result.exit_code == 0, result.output
    assert "Δ ssdgs/official − gs3" in result.output
