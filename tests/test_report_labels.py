"""One label rule for every table, figure legend and JSON record (#47): a label names the method,
the variant and every setting that differs from the suite's defaults, and two different experiments
never share one."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from test_report_runs import metric_values, write_run

from olatbench.cli import main
from olatbench.reports.collect import collect
from olatbench.reports.experiments import experiment_labels, override_settings
from olatbench.reports.figures import ComparisonRow, close, comparison_figure
from olatbench.reports.runs_tables import overview_table, scene_table


def _row_labels(table) -> list[str]:
    return [row.labels[0] for row in table.blocks[0].rows]


def test_overrides_are_read_from_the_variant_label():
    assert override_settings("default") == ("default", [])
    assert override_settings("mini~iterations=200,lr=0.1") == ("mini", ["iterations=200", "lr=0.1"])
    assert override_settings("default~scale=[1,1,1],x=2") == ("default", ["scale=[1,1,1]", "x=2"])


def test_a_lone_run_with_a_variant_and_overrides_is_not_labelled_by_its_method_alone(tmp_path):
    """The issue's case: ``ssdgs --variant mini --iterations 200`` read just ``ssdgs``."""
    write_run(
        tmp_path,
        "ssdgs",
        "mini~iterations=200",
        "mini",
        "translucent",
        0,
        metric_values(20.0),
        config={"iterations": 200},
    )
    write_run(tmp_path, "gs3", "default", "mini", "translucent", 0, metric_values(21.0))
    frame = collect(tmp_path)
    expected = ["gs3", "ssdgs/mini (iterations=200)"]
    assert sorted(_row_labels(scene_table(frame, metrics=["psnr"], splits=["test"]))) == expected
    assert sorted(_row_labels(overview_table(frame, metrics=["psnr"], splits=["test"]))) == expected
    result = CliRunner().invoke(main, ["report", str(tmp_path), "--json", "--metrics", "psnr"])
    assert result.exit_code == 0, result.output
    # the tables' labels
    assert sorted({record["label"] for record in json.loads(result.output)}) == expected


def test_two_methods_never_share_a_label(tmp_path):
    """Ablation presets used to read as the paper's label alone ("A: Diff") in every table, whatever
    the method: two methods' ablation-A runs then made one row averaging both."""
    write_run(tmp_path, "ssdgs", "ablation-A", "mini", "translucent", 0, metric_values(20.0))
    write_run(tmp_path, "3dgs", "ablation-A", "mini", "translucent", 0, metric_values(30.0))
    table = scene_table(collect(tmp_path), metrics=["psnr"], splits=["test"])
    assert sorted(_row_labels(table)) == ["3dgs/ablation-A", "ssdgs/ablation-A"]
    assert table.cell("PSNR ↑", ("ssdgs/ablation-A",), "translucent/Test").number == 20.0
    assert table.cell("PSNR ↑", ("3dgs/ablation-A",), "translucent/Test").number == 30.0


def test_a_resolution_other_than_the_suites_own_is_in_the_label(tmp_path):
    write_run(
        tmp_path / "mini",
        "gs3",
        "default",
        "mini",
        "translucent",
        0,
        metric_values(20.0),
        resolution=[64, 48],
    )
    assert _row_labels(scene_table(collect(tmp_path / "mini"))) == ["gs3 (resolution=64x48)"]
    write_run(
        tmp_path / "gs3",
        "gs3",
        "default",
        "gs3",
        "translucent",
        0,
        metric_values(20.0),
        resolution=[512, 512],
    )
    # the gs3 suite's own size
    assert _row_labels(scene_table(collect(tmp_path / "gs3"), suite="gs3")) == ["gs3"]


def test_labels_differ_for_every_experiment_of_a_busy_folder(tmp_path):
    """Methods, variants, overrides, resolutions, configs and data versions mixed: one label per
    (experiment, data)."""
    runs = tmp_path / "runs"
    for seed in (0, 1):
        write_run(runs, "ssdgs", "default", "mini", "translucent", seed, metric_values(20.0))
        write_run(
            runs,
            "ssdgs",
            "default~iterations=200",
            "mini",
            "translucent",
            seed,
            metric_values(21.0),
        )
        write_run(
            runs, "ssdgs", "mini~iterations=200", "mini", "translucent", seed, metric_values(22.0)
        )
        write_run(
            runs, "3dgs", "default~iterations=200", "mini", "translucent", seed, metric_values(23.0)
        )
    write_run(
        runs / "old",
        "ssdgs",
        "default",
        "mini",
        "translucent",
        0,
        metric_values(24.0),
        config={"lr": 1},
    )
    write_run(
        runs / "lowres",
        "ssdgs",
        "default",
        "mini",
        "translucent",
        0,
        metric_values(25.0),
        resolution=[8, 6],
    )
    write_run(
        runs / "redata",
        "3dgs",
        "default~iterations=200",
        "mini",
        "translucent",
        2,
        metric_values(26.0),
        data="re-rendered",
    )
    frame = collect(runs)
    labels = experiment_labels(frame)
    per_experiment = frame.assign(label=labels).groupby(["experiment", "data"])["label"].unique()
    assert all(len(names) == 1 for names in per_experiment)  # one label per experiment
    assert len(set(labels)) == len(per_experiment)  # and never one label for two
    assert set(labels) >= {
        "ssdgs/mini (iterations=200)",
        "3dgs (iterations=200, data v1)",
        "3dgs (iterations=200, data v2)",
        "ssdgs (resolution=8x6)",
    }


def _overlaps(boxes) -> list[tuple[int, int]]:
    return [
        (i, j)
        for i, a in enumerate(boxes)
        for j, b in enumerate(boxes[i + 1 :], i + 1)
        if a.width and b.width and a.overlaps(b)
    ]


def test_no_two_texts_of_a_comparison_grid_overlap_with_five_long_labels():
    """The issue's figure: five methods whose labels are long (``3dgs/default~iterations=200 (10.47
    dB)`` over its neighbour). Every title must stay inside its own panel and no two texts may share
    a pixel."""
    truth = np.full((48, 64, 3), 0.5, np.float32)
    labels = [
        f"{method}/mini (iterations=200, lr_position=0.00016, resolution=64x48)"
        for method in ("3dgs", "gs3", "ssdgs", "nrhints", "rng")
    ]
    rows = [
        ComparisonRow(
            frame, truth, [(label, truth * (0.6 + 0.08 * i)) for i, label in enumerate(labels)]
        )
        for frame in ("r_003", "r_017")
    ]
    figure = comparison_figure(rows)
    try:
        figure.canvas.draw()
        renderer = figure.canvas.get_renderer()
        panels = [axis for axis in figure.axes if axis.images]
        titles = [axis.title.get_window_extent(renderer) for axis in panels]
        for axis, box in zip(panels, titles, strict=True):
            panel = axis.get_window_extent(renderer)
            # within its panel's width
            assert panel.x0 - 1 <= box.x0 and box.x1 <= panel.x1 + 1, axis.get_title()
        legend = figure.legends[0]
        texts = [text.get_window_extent(renderer) for text in legend.get_texts()]
        assert (
            _overlaps(titles + texts + [axis.get_window_extent(renderer) for axis in panels]) == []
        )
        spelt = " ".join(text.get_text().replace("\n", " ") for text in legend.get_texts())
        for label in labels:  # every full label is spelt out under the grid
            assert " ".join(label.split()) in " ".join(spelt.split())
    finally:
        close(figure)


@pytest.mark.parametrize("count", [1, 12])
def test_the_key_legend_scales_with_the_number_of_methods(count):
    truth = np.full((12, 16, 3), 0.5, np.float32)
    labels = [f"method{i}/variant~iterations={i}" for i in range(count)]
    figure = comparison_figure([ComparisonRow("f", truth, [(label, truth) for label in labels])])
    try:
        assert len(figure.legends[0].get_texts()) == count
    finally:
        close(figure)
