"""Each ablation grid names its reference variant (`AblationGrid`); the plan records grid and
reference in job.json (`Job.ablation`, outside the job's identity); the reports read them from
there, and from the method's spec for job.json files written before the record existed
(`olatbench.bench.ablation.job_ablation`)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import test_runner_support as support
from test_report_runs import metric_values, write_run

from olatbench.bench.ablation import job_ablation
from olatbench.bench.execute import run_job
from olatbench.bench.jobs import Job
from olatbench.bench.plan import make_plan
from olatbench.bench.store import JOB_FILE, job_state
from olatbench.methods.registry import get_spec, register
from olatbench.methods.spec import AblationGrid, MethodSpec
from olatbench.reports.collect import collect
from olatbench.reports.runs_tables import ablation_table

GRADED = MethodSpec(
    name="graded",
    description="the trivial method with ablation grids that name their references",
    implementation="test_runner_support:TrivialMethod",
    config="test_runner_support:TrivialConfig",
    presets=support.TrivialMethod.presets,
    ablations={
        "components": AblationGrid(tuple(f"ablation-{x}" for x in "ABC"), reference="ablation-B"),
        "noise": AblationGrid(("default", "schedule-H"), reference="default"),
    },
)


@pytest.fixture()
def graded():
    register(GRADED)
    return GRADED


def test_a_grid_reference_is_one_of_its_variants():
    with pytest.raises(ValueError, match="its reference 'ablation-D' is not one of them"):
        AblationGrid(("ablation-A", "ablation-B"), reference="ablation-D")
    grids = get_spec("ssdgs").ablations
    assert {name: grid.reference for name, grid in grids.items()} == {
        "components": "ablation-D",
        "schedule": "schedule-I",
        "shadow-on-sss": "default",
    }


def test_the_grid_a_variant_belongs_to(graded):
    assert graded.ablation_of("ablation-C") == {"grid": "components", "reference": "ablation-B"}
    assert graded.ablation_of("ablation-C~iterations=5") == {
        "grid": "components",
        "reference": "ablation-B",
    }
    assert graded.ablation_of("default") is None  # a plain run is no ablation ...
    # ... unless asked
    assert graded.ablation_of("default", "noise") == {"grid": "noise", "reference": "default"}
    assert graded.ablation_of("schedule-I") is None
    # a class's plain grids name no reference
    assert get_spec("trivial").ablation_of("ablation-A") is None


def test_the_plan_records_grid_and_reference_in_job_json_outside_the_id(graded, tmp_path):
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    jobs = make_plan(
        "graded",
        support.tiny_suite(scenes=("Alpha",)),
        tmp_path / "runs",
        data_root=data,
        ablation="noise",
        progress=False,
    )
    assert [(job.variant, job.ablation) for job in jobs] == [
        ("default", {"grid": "noise", "reference": "default"}),
        ("schedule-H", {"grid": "noise", "reference": "default"}),
    ]
    job = jobs[0]
    assert "ablation" not in job.identity()
    assert job.id == dataclasses.replace(job, ablation=None).with_id().id
    assert Job.from_json(json.loads(json.dumps(job.to_json()))) == job
    # a job.json written before the field: still read, same id, and its finished folder is done, not
    # stale
    assert run_job(job, progress=False).status == "done"
    written = json.loads((Path(job.folder) / JOB_FILE).read_text())
    assert written["ablation"] == {"grid": "noise", "reference": "default"}
    del written["ablation"]
    (Path(job.folder) / JOB_FILE).write_text(json.dumps(written))
    assert Job.from_json(written).ablation is None and Job.from_json(written).id == job.id
    assert job_state(job.folder, job.id).state == "done"


def test_reports_take_the_reference_from_job_json(graded, tmp_path):
    """The recorded reference decides the significance marks; "null" keeps a run out of the ablation
    table; a job.json without the key falls back to the method's spec."""
    root = tmp_path / "runs"
    psnrs = {
        "ablation-A": (25.0, 25.2, 24.8),
        "ablation-B": (30.0, 30.2, 29.8),
        "ablation-C": (30.1, 29.9, 30.3),
    }
    for variant, values in psnrs.items():
        for seed, psnr in enumerate(values):
            path = write_run(root, "trivial", variant, "tiny", "Alpha", seed, metric_values(psnr))
            (path.parent / JOB_FILE).write_text(
                json.dumps(
                    {
                        "id": f"trivial-{variant}-Alpha-{seed}",
                        "ablation": {"grid": "mine", "reference": "ablation-B"},
                    }
                )
            )
    outside = write_run(root, "trivial", "default", "tiny", "Alpha", 0, metric_values(40.0))
    (outside.parent / JOB_FILE).write_text(
        json.dumps({"id": "trivial-default-Alpha-0", "ablation": None})
    )
    frame = collect(root)
    assert set(frame["ablation_grid"]) == {"mine", ""}
    table = ablation_table(frame, method="trivial", metrics=["psnr"], splits=["test"])
    rows = [row.labels[0] for row in table.blocks[0].rows]
    assert not any("default" in row for row in rows)
    marks = {row.labels[0]: row.cells[0].marks for row in table.blocks[0].rows}
    # against B (recorded), not the spec's nothing
    assert [marks[row] for row in rows] == [("s",), (), ("n",)]


def test_job_json_without_the_record_asks_the_spec():
    assert job_ablation({"id": "x"}, "ssdgs", "schedule-J") == {
        "grid": "schedule",
        "reference": "schedule-I",
    }
    assert job_ablation(None, "ssdgs", "ablation-A~iterations=10") == {
        "grid": "components",
        "reference": "ablation-D",
    }
    # recorded: outside
    assert job_ablation({"id": "x", "ablation": None}, "ssdgs", "ablation-A") is None
    assert job_ablation({"id": "x"}, "not-installed", "ablation-A") is None
