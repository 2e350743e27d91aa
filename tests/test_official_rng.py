"""``rng-official`` (sssssy/RNG_release @ 4e8748e) through the runner with a stand-in checkout
(tests/official_standins.py): its two training stages and render as the README runs them, scaled for
mini, and a rerun after a failure redoing only the commands that had not finished."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from official_standins import write_checkout
from test_official import PERFECT_PSNR, plan, suite_of, write_data

from olatbench.atomic import write_json
from olatbench.bench.executors import run_inline
from olatbench.bench.results import read_results
from olatbench.cli import main
from olatbench.datasets import load_scene
from olatbench.methods.official.code import OfficialConfig
from olatbench.methods.official.process import OfficialRunError
from olatbench.methods.official.runner import prepare, step_file
from olatbench.methods.official.settings import CodeSettings
from olatbench.methods.official.specs import RNG_CODE
from olatbench.reports.published import lookup, paper_method


def flag_value(argv: list[str], flag: str) -> str:
    assert argv.count(flag) == 1, (flag, argv)
    return argv[argv.index(flag) + 1]


def test_rng_runs_stage_1_then_stage_2_from_its_checkpoint_then_renders(tmp_path) -> None:
    """mini: 3000 steps for the README's 100K, so stage 1 ends at 900 (its 30000 scaled) and stage 2
    loads chkpnt900.pth; the schedule flags are scaled in both stages; the renders are paired with
    their frames."""
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "rng-official")
    [job] = plan(
        "rng-official",
        suite_of("mini"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [outcome] = run_inline([job], progress=False)
    folder = Path(job.folder)
    assert outcome.status == "done", (folder / "log.txt").read_text()
    results = read_results(folder / "results.json")
    commands = results["official"]["commands"]
    assert [c["step"] for c in commands] == ["train", "train_stage2", "render"]
    stage1, stage2, render = (c["argv"] for c in commands)
    model = folder / "official" / "model"
    assert (
        flag_value(stage1, "--iterations") == "900"
        and flag_value(stage1, "--save_iterations") == "900"
    )
    assert flag_value(stage1, "--densify_until_iter") == "900" and "--load_pc" not in stage1
    assert (
        flag_value(stage2, "--iterations") == "3000"
        and flag_value(stage2, "--load_pc") == f"{model}/chkpnt900.pth"
    )
    for argv in (stage1, stage2):  # RNG's defaults, scaled by 3000 / 100000
        assert (
            flag_value(argv, "--densify_from_iter") == "15"
            and flag_value(argv, "--opacity_reset_interval") == "90"
        )
    # the default 15000: no densification in stage 2
    assert flag_value(stage2, "--densify_until_iter") == "450"
    assert all(
        flag in stage2
        for flag in ("--defer_shading", "--shadow_map", "--shadow_grad", "--depth_mlp")
    )
    # black on every suite (the paper's appendix)
    assert "--white_background" not in stage1 + stage2
    assert flag_value(render, "--iteration") == "3000" and "--skip_train" in render
    assert (checkout / "calls.txt").read_text().split() == ["stage1", "stage2", "render"]
    per_image = results["metrics"]["test"]["per_image"]
    assert list(per_image) == [frame.frame_id for frame in load_scene(data / "Alpha").split("test")]
    assert all(values["psnr"] > PERFECT_PSNR for values in per_image.values()), per_image
    seconds = [c["seconds"] for c in commands]
    assert results["timing"]["train_seconds"] == pytest.approx(seconds[0] + seconds[1], abs=2e-3)


def test_renders_whose_ground_truth_is_another_frame_are_refused(tmp_path) -> None:
    """render.py writes each view's ground truth beside its render (render.py:82): a render script
    that rendered frame i+1 as render i (the stand-in's SHIFT) is caught by it, before anything is
    scored."""
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "rng-official")
    (checkout / "SHIFT").write_text("")
    [job] = plan(
        "rng-official",
        suite_of("mini"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [outcome] = run_inline([job], progress=False)
    assert (
        outcome.status == "failed"
        and "render 0 was rendered for another image than frame" in outcome.error
    )


def test_a_rerun_after_stage_2_failed_redoes_only_stage_2_and_the_render(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", "rng-official")
    # stage 2's command line holds it, stage 1's does not
    (checkout / "FAIL").write_text("--defer_shading")
    [job] = plan(
        "rng-official",
        suite_of("mini"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    [failed] = run_inline([job], progress=False)
    assert failed.status == "failed" and "train_stage2 failed with exit code 3" in failed.error
    (checkout / "FAIL").unlink()
    [outcome] = run_inline([job], progress=False)
    log = (Path(job.folder) / "log.txt").read_text()
    assert outcome.status == "done", log
    assert (checkout / "calls.txt").read_text().split() == ["stage1", "stage2", "stage2", "render"]
    assert "train: finished by an earlier attempt of this job" in log
    commands = read_results(Path(job.folder) / "results.json")["official"]["commands"]
    assert [c["resumed"] for c in commands] == [True, False, False] and commands[0][
        "exit_code"
    ] == 0


def test_a_finished_stage_is_kept_only_for_the_same_command_line(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    scene = load_scene(data / "Alpha")
    settings = CodeSettings(
        method="rng-official",
        checkout=str(write_checkout(tmp_path / "checkout", "rng-official")),
        python=sys.executable,
    )

    def prepared(iterations: int):
        return prepare(
            RNG_CODE,
            settings,
            scene,
            tmp_path / "work",
            "mini",
            "train",
            "test",
            None,
            OfficialConfig(iterations=iterations, reference_iterations=100_000),
        )

    first = prepared(3000)
    assert not any(record.resumed for record in first.commands)
    first.model_dir.mkdir()
    (first.model_dir / "chkpnt900.pth").write_text("900")
    write_json(step_file(first.work, "train"), {"argv": first.commands[0].argv, "seconds": 5.0})
    again = prepared(3000)
    assert [record.resumed for record in again.commands] == [True, False, False]
    assert again.commands[0].seconds == 5.0 and (again.model_dir / "chkpnt900.pth").is_file()
    assert (again.scene_dir / "transforms_test.json").is_file()
    other = prepared(2000)  # stage 1 would end at 600: its command line differs, nothing is kept
    assert not any(record.resumed for record in other.commands) and not other.model_dir.exists()


def test_a_run_too_short_for_stage_1_is_refused_before_anything_runs(tmp_path) -> None:
    """Unscaled (no reference_iterations), stage 1 is the README's 30000 steps: a 200-step run has
    no stage 2."""
    data = write_data(tmp_path / "data")
    settings = CodeSettings(
        method="rng-official",
        checkout=str(write_checkout(tmp_path / "checkout", "rng-official")),
        python=sys.executable,
    )
    with pytest.raises(
        OfficialRunError,
        match=r"stage1_iterations = 30000 .* must lie between 1 and iterations - 1",
    ):
        prepare(
            RNG_CODE,
            settings,
            load_scene(data / "Alpha"),
            tmp_path / "work",
            "nrhints",
            "train",
            "test",
            None,
            OfficialConfig(iterations=200),
        )
    assert not (tmp_path / "work").exists()


def test_methods_show_lists_both_stages_with_their_sources_and_rng_is_the_papers_row() -> None:
    shown = CliRunner().invoke(main, ["methods", "show", "rng-official"]).output
    assert "sssssy/RNG_release @ 4e8748e1cc9915b1c9d67538d2ec46dc59c0d7f4 (verified)" in shown
    assert (
        "train: <launcher> train.py -s {scene} -m {model} --iterations {stage1_iterations}" in shown
    )
    assert (
        "train_stage2: <launcher> train.py" in shown
        and "--load_pc {model}/chkpnt{stage1_iterations}.pth" in shown
    )
    assert "source of train_stage2 (deferred shading): README.md:29" in shown
    assert "{stage1_iterations} = 30000" in shown
    listing = CliRunner().invoke(main, ["methods", "list"]).output
    assert "rng-official      [official, verified]" in listing and "no public code" not in listing
    # report --published puts the paper's RNG rows beside it
    assert paper_method("rng-official") == "RNG"
    assert (
        lookup("RNG", "nrhints", "Cat", "test", "psnr") is not None
        and lookup("RNG", "gs3", "AnisoMetal", "test", "psnr") is not None
    )
