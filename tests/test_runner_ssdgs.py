"""SSD-GS through the runner at a tiny size: end to end, and an exact resume after an
interruption."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import test_runner_support as support
import torch

from olatbench.bench.checkpoints import list_checkpoints
from olatbench.bench.execute import run_job
from olatbench.bench.plan import PlanOptions, make_plan
from olatbench.bench.results import read_results

# SSD-GS's light-view pass (gaussians-support helper)
pytest.importorskip("olatbench.gaussians.shadow")
from olatbench.methods.ssdgs import SSDGS

ITERATIONS = 30


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return support.write_tiny_data(tmp_path_factory.mktemp("ssdgs") / "data", scenes=("Alpha",))


def plan(data, out, iterations=ITERATIONS, **kwargs):
    return make_plan(
        "ssdgs",
        support.tiny_suite(scenes=("Alpha",)),
        out,
        variants=["mini"],
        iterations=iterations,
        data_root=data,
        progress=False,
        **kwargs,
    )


def smaller(job, **config):
    """The same job with config overrides (and the id they give)."""
    return dataclasses.replace(job, config={**job.config, **config}).with_id()


def test_ssdgs_runs_end_to_end_at_a_few_iterations(data, tmp_path):
    """Default-run sized: 16 iterations, 300 Gaussians (SSD-GS on CPU takes seconds per step)."""
    job = plan(data, tmp_path / "runs", iterations=16, options=PlanOptions(save_components=True))[0]
    # densify_from past the run: no density control (16 steps would densify under the schedule
    # floors)
    job = smaller(job, num_init_gaussians=300, shadow_resolution=32, densify_from=100_000)
    outcome = run_job(job, progress=False)
    assert outcome.status == "done", (Path(job.folder) / "error.txt").read_text()
    results = read_results(Path(job.folder) / "results.json")
    assert results["model"]["iterations"] == 16 and results["model"]["num_gaussians"] == 300
    assert results["job"]["config"]["num_init_gaussians"] == 300
    assert (results["job"]["config"]["cull_shading"], results["job"]["config"]["cull_epsilon"]) == (
        # the contribution-culling switch is part of the recorded config
        False,
        SSDGS.config_class().cull_epsilon,
    )
    for split in ("train", "test"):
        assert results["metrics"][split]["mean"]["psnr"] > 0
    components = {p.name for p in (Path(job.folder) / "components" / "test").iterdir()}
    assert {"diffuse", "specular", "sss", "shadow"} <= components
    assert len(list((Path(job.folder) / "renders" / "test").glob("*.png"))) == 2
    # The C++ kernels build here, so every stage runs them; the log says so after set-up.
    stages = ("rasterizer", "projection", "binning", "light_pass", "ssim", "shading")
    assert results["resources"]["device"] == "cpu"
    assert results["resources"]["backends"] == {
        **dict.fromkeys(stages, "cpu"),
        "network_precision": "fp32",
    }
    assert (
        "device cpu; backends: rasterizer=cpu, projection=cpu"
        in (Path(job.folder) / "log.txt").read_text()
    )


def test_bf16_networks_are_recorded_in_results(data, tmp_path, monkeypatch):
    """``network_precision`` is in the recorded config and among the backends of results.json."""
    from olatbench.methods.shading import precision

    # allowed on any CPU for this test
    monkeypatch.setattr(precision, "cpu_flags", lambda: ["avx512_bf16"])
    job = smaller(
        plan(data, tmp_path / "runs", iterations=4)[0],
        num_init_gaussians=200,
        shadow_resolution=24,
        network_precision="bf16",
    )
    outcome = run_job(job, progress=False)
    assert outcome.status == "done", (Path(job.folder) / "error.txt").read_text()
    results = read_results(Path(job.folder) / "results.json")
    assert results["job"]["config"]["network_precision"] == "bf16"
    assert results["resources"]["backends"]["network_precision"] == "bf16"
    assert "network_precision=bf16" in (Path(job.folder) / "log.txt").read_text()


def test_test_time_refinement_is_run_and_recorded(data, tmp_path):
    """Each test view is refined before it is scored; results say so, per frame; off by default
    (null)."""
    base = smaller(
        plan(data, tmp_path / "base", iterations=8)[0], num_init_gaussians=200, shadow_resolution=24
    )
    refined_job = smaller(
        plan(data, tmp_path / "refined", iterations=8)[0],
        num_init_gaussians=200,
        shadow_resolution=24,
        refine_camera=True,
        test_time_refinement=True,
        test_time_steps=3,
    )
    assert refined_job.id != base.id  # a different, recorded configuration
    for job in (base, refined_job):
        assert run_job(job, progress=False).status == "done", (
            Path(job.folder) / "error.txt"
        ).read_text()
    assert (
        read_results(Path(base.folder) / "results.json")["evaluation"]["test_time_refinement"]
        is None
    )
    results = read_results(Path(refined_job.folder) / "results.json")
    record = results["evaluation"]["test_time_refinement"]
    assert record["split"] == "test" and record["seconds"] > 0
    assert set(record["frames"]) == set(results["metrics"]["test"]["per_image"])
    for summary in record["frames"].values():
        assert summary["steps"] == 3 and summary["loss_after"] <= summary["loss_before"] + 1e-6
    assert results["job"]["config"]["test_time_refinement"] is True


def test_interleaved_test_pose_fitting_is_run_recorded_and_footnoted(data, tmp_path):
    """The runner gives the test views to the method, which fits them while training (4 training
    views: test passes after steps 4 and 8); results.json records the mode and each frame's offsets;
    the report footnotes the test numbers (not the train ones)."""
    from olatbench.reports.collect import collect
    from olatbench.reports.runs_tables import scene_table

    job = smaller(
        plan(data, tmp_path / "runs", iterations=10)[0],
        num_init_gaussians=200,
        shadow_resolution=24,
        refine_camera=True,
        refine_light=True,
        refine_camera_from=0,
        refine_light_from=0,
        test_pose_fitting="interleaved",
    )
    assert run_job(job, progress=False).status == "done", (
        Path(job.folder) / "error.txt"
    ).read_text()
    results = read_results(Path(job.folder) / "results.json")
    record = results["evaluation"]["test_pose_fitting"]
    assert record["mode"] == "interleaved" and record["split"] == "test"
    assert set(record["frames"]) == set(results["metrics"]["test"]["per_image"])
    assert all(
        frame["rotation_deg"] > 0 and frame["light_offset"] > 0
        for frame in record["frames"].values()
    )
    table = scene_table(collect(tmp_path / "runs"), suite=job.suite, metrics=("psnr",))
    assert any(
        note.startswith("f:") and "test_pose_fitting=interleaved" in note
        for note in table.footnotes
    )
    marks = {
        column: cell.marks
        for block in table.blocks
        for row in block.rows
        for column, cell in zip(table.columns, row.cells, strict=True)
    }
    assert {column: "f" in cell_marks for column, cell_marks in marks.items()} == {
        column: column.endswith("/Test") for column in marks
    }


@pytest.mark.slow
def test_ssdgs_mini_preset_runs_end_to_end(data, tmp_path):
    job = plan(data, tmp_path / "runs", options=PlanOptions(save_components=True))[0]
    outcome = run_job(job, progress=False)
    assert outcome.status == "done", (Path(job.folder) / "error.txt").read_text()
    results = read_results(Path(job.folder) / "results.json")
    assert results["model"]["iterations"] == ITERATIONS and results["model"]["num_gaussians"] > 0
    assert (
        results["job"]["config"]["num_init_gaussians"]
        == SSDGS.presets["mini"]["num_init_gaussians"]
    )
    for split in ("train", "test"):
        assert results["metrics"][split]["mean"]["psnr"] > 0
    components = {p.name for p in (Path(job.folder) / "components" / "test").iterdir()}
    assert {"diffuse", "specular", "sss", "shadow"} <= components
    assert len(list((Path(job.folder) / "renders" / "test").glob("*.png"))) == 2


@pytest.mark.slow
def test_ssdgs_resumes_exactly_through_the_runner(data, tmp_path, monkeypatch):
    options = PlanOptions(checkpoint_every=10)
    interrupted = plan(data, tmp_path / "interrupted", options=options)[0]
    reference = plan(data, tmp_path / "reference", options=options)[0]
    original = SSDGS.train_step

    def ctrl_c_at_15(self, step):
        if step == 15:
            raise KeyboardInterrupt
        return original(self, step)

    monkeypatch.setattr(SSDGS, "train_step", ctrl_c_at_15)
    with pytest.raises(KeyboardInterrupt):
        run_job(interrupted, progress=False)
    assert list_checkpoints(interrupted.folder)[-1][0] == 10
    monkeypatch.setattr(SSDGS, "train_step", original)
    assert run_job(interrupted, progress=False).status == "done"
    assert run_job(reference, progress=False).status == "done"
    a = read_results(Path(interrupted.folder) / "results.json")
    b = read_results(Path(reference.folder) / "results.json")
    assert a["metrics"] == b["metrics"]
    model_a = torch.load(list_checkpoints(interrupted.folder)[-1][1], weights_only=True)["method"][
        "model"
    ]
    model_b = torch.load(list_checkpoints(reference.folder)[-1][1], weights_only=True)["method"][
        "model"
    ]
    assert model_a.keys() == model_b.keys()
    assert all(torch.equal(model_a[key], model_b[key]) for key in model_a)


def test_speed_benchmark_measures_a_trained_job_folder(data, tmp_path, capsys, monkeypatch):
    """benchmarks/bench_ssdgs.py --jobs: a job folder's trained model, its own size and config, one
    row each."""
    import runpy

    job = smaller(
        plan(data, tmp_path / "runs", iterations=4)[0], num_init_gaussians=150, shadow_resolution=16
    )
    assert run_job(job, progress=False).status == "done"
    script = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_ssdgs.py"
    monkeypatch.setattr(
        "sys.argv",
        ["bench_ssdgs.py", "--states", "--repeats", "1", "--threads", "1", "--jobs", job.folder],
    )
    threads = torch.get_num_threads()
    try:
        runpy.run_path(str(script), run_name="__main__")
    finally:  # the script sets both for its process
        torch.set_num_threads(threads)
        torch.set_flush_denormal(False)
    lines = capsys.readouterr().out.strip().splitlines()
    row = lines[1].split()
    # scene, view width (the tiny suite's 64 px), trained Gaussians
    assert row[:3] == ["Alpha", "64", "150"]
    # by what each measures: mlp_efficiency_min=..., bf16 ..., culling ...
    summaries = {
        line.split()[2].split("=")[0]: line for line in lines if line.startswith("SUMMARY")
    }
    assert summaries.keys() >= {"mlp_efficiency_min", "bf16", "culling"}, summaries
    # the bf16 networks timed beside fp32 in the same run
    assert "step speed-up" in summaries["bf16"]
    # the culled variant, at eps 0 and the config's default, in the same run
    culling = summaries["culling"]
    assert culling.startswith("SUMMARY bench_ssdgs culling speed-up") and "Alpha@0=" in culling
    assert sum("cull eps=" in line for line in lines) == 2
