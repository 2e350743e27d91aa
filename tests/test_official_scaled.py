"""Official runs at the mini suite's scale: the train scripts' schedule scaled like the native
presets' and the native methods' initial points written where the authors' loaders read them
(docs/official.md)."""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from datasets_trees import write_gs3_tree
from official_standins import write_checkout
from test_official import plan, suite_of, write_data

from olatbench.datasets import load_scene
from olatbench.gaussians.ply import read_ply_points
from olatbench.methods.initialisation import initial_points
from olatbench.methods.official.code import OfficialConfig
from olatbench.methods.official.process import OfficialRunError
from olatbench.methods.official.runner import prepare
from olatbench.methods.official.settings import CodeSettings
from olatbench.methods.official.specs import GS3_CODE, NRHINTS_CODE, RNG_CODE, SSDGS_CODE
from olatbench.methods.training import initial_model


def flag_value(argv: list[str], flag: str) -> str:
    """The value of the last occurrence of ``flag``."""
    return argv[max(i for i, arg in enumerate(argv) if arg == flag) + 1]


def test_the_schedule_flags_scale_on_the_command_line_and_from_the_parsers_defaults() -> None:
    values = {"scene": "/s", "model": "/m", "checkout": "/c", "iterations": 3000}
    [(_, train), (_, render)] = SSDGS_CODE.commands
    argv = SSDGS_CODE.command(
        "train",
        train,
        values,
        "mini",
        ("--densify_until_iter", "7"),
        scene="x",
        schedule_lengths=(3000, 60000),
    )
    assert flag_value(argv, "--unfreeze_iterations") == "250"  # on the command line: 5000
    assert flag_value(argv, "--position_lr_max_steps") == "2500"  # the suite's 50000
    # the parser's default 3000, appended
    assert flag_value(argv, "--opacity_reset_interval") == "150"
    assert flag_value(argv, "--scatter_warmup_step") == "450"  # SSD-GS's own option
    assert (
        flag_value(argv, "--iterations") == "3000"
        and flag_value(argv, "--save_iterations") == "3000"
    )
    assert "--densification_interval" not in argv  # a cadence: not scaled
    # the user's own flag comes last, as given
    assert flag_value(argv, "--densify_until_iter") == "7"
    tiny = SSDGS_CODE.command(
        "train", train, values, "mini", scene="x", schedule_lengths=(3, 300000)
    )
    assert flag_value(tiny, "--opacity_reset_interval") == "1"  # taken modulo by train.py: never 0
    assert flag_value(tiny, "--unfreeze_iterations") == "1"
    unscaled = SSDGS_CODE.command("train", train, values, "mini", scene="x")
    assert (
        flag_value(unscaled, "--unfreeze_iterations") == "5000"
        and "--opacity_reset_interval" not in unscaled
    )
    assert SSDGS_CODE.command(
        "render", render, values, "mini", scene="x", schedule_lengths=(3000, 60000)
    ) == SSDGS_CODE.command("render", render, values, "mini", scene="x")
    gs3 = GS3_CODE.command(
        "train", GS3_CODE.commands[0][1], values, "mini", scene="x", schedule_lengths=(3000, 60000)
    )
    assert flag_value(gs3, "--spcular_freeze_step") == "450" and "--scatter_warmup_step" not in gs3


@pytest.mark.parametrize("method", ["ssdgs-official", "gs3-official"])
def test_mini_jobs_scale_the_schedule_and_start_from_the_native_points(tmp_path, method) -> None:
    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", method)
    [job] = plan(
        method,
        suite_of("mini"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
    )
    assert {k: job.config[k] for k in ("iterations", "reference_iterations", "init_points")} == {
        "iterations": 3000,
        "reference_iterations": 60000,
        "init_points": 2000,
    }
    assert "--densify_until_iter" in job.config["preset_args"]
    # JSON lists
    assert OfficialConfig(**{**job.config, "train_args": ["--x", "1"]}).train_args == ("--x", "1")
    code = SSDGS_CODE if method == "ssdgs-official" else GS3_CODE
    scene = load_scene(job.scene_path, format=job.scene_format)
    config = OfficialConfig(**{**job.config, "iterations": 300})
    settings = CodeSettings.from_json(job.official)
    runs = [
        prepare(
            code,
            settings,
            scene,
            tmp_path / f"work{seed}",
            job.suite,
            job.train_split,
            job.test_split,
            None,
            config,
            seed,
        )
        for seed in (0, 0, 1)
    ]
    train = runs[0].commands[0].argv
    assert flag_value(train, "--unfreeze_iterations") == "25"  # 5000 at 60K, run at 300 steps
    assert flag_value(train, "--densify_from_iter") == "20"  # the preset's preset_args: 4000 at 60K
    # 30000 at 60K (the parser's 3000 overridden)
    assert flag_value(train, "--opacity_reset_interval") == "150"
    ply = runs[0].scene_dir / "points3d.ply"
    header = ply.read_bytes().split(b"end_header")[0].decode()
    # what the 3DGS loaders' fetchPly reads by name
    assert all(f"property float {name}" in header for name in ("x", "y", "z", "nx", "ny", "nz"))
    assert all(f"property uchar {name}" in header for name in ("red", "green", "blue"))
    points, colours = read_ply_points(ply)
    cameras = [frame.camera for frame in scene.split(job.train_split)]
    assert points.shape == (2000, 3) and np.array_equal(points, initial_points(cameras, 2000, 0))
    assert np.allclose(colours, 128 / 255)
    # same seed, same points
    assert np.array_equal(points, read_ply_points(runs[1].scene_dir / "points3d.ply")[0])
    assert not np.allclose(points, read_ply_points(runs[2].scene_dir / "points3d.ply")[0])
    # the very centres a native mini run (init_radius None, 2000 Gaussians) starts from with the
    # same seed
    from olatbench.bench.views import load_views
    from olatbench.methods.ssdgs import SSDGS

    native = SSDGS.resolve_config("mini")
    views = load_views(scene.split(job.train_split), job)
    model = initial_model(views, native, {}, 0, torch.device("cpu"))
    assert native.num_init_gaussians == 2000 and native.init_radius is None
    assert np.array_equal(model.means.detach().numpy(), points)


def test_settings_a_code_cannot_use_are_refused_before_anything_runs(tmp_path) -> None:
    data = write_data(tmp_path / "data")
    scene = load_scene(data / "Alpha", format="nrhints")
    checkout = write_checkout(tmp_path / "checkout", "nrhints-official")
    settings = CodeSettings(
        method="nrhints-official", checkout=str(checkout), python=sys.executable
    )
    for field, message in (
        (
            "init_points",
            "init_points=10 is set, but nrhints-official's loader reads no initial point cloud",
        ),
        (
            "reference_iterations",
            "reference_iterations=10 is set, but olatbench knows no "
            "schedule flags of nrhints-official",
        ),
    ):
        with pytest.raises(OfficialRunError, match=re.escape(message)):
            prepare(
                NRHINTS_CODE,
                settings,
                scene,
                tmp_path / "work",
                "mini",
                "train",
                "test",
                None,
                OfficialConfig(iterations=5, **{field: 10}),
            )
    assert not (tmp_path / "work").exists()  # refused before the work folder was emptied or written
    with pytest.raises(ValueError, match="init_points"):
        OfficialConfig(init_points=0)


@pytest.mark.parametrize(
    ("code", "white"),
    [
        (SSDGS_CODE, ["--white_background"]),
        (GS3_CODE, ["--white_background"]),
        (RNG_CODE, ["--white_background"]),
        (NRHINTS_CODE, ["--config.data.white-background", "True"]),
    ],
)
def test_a_scene_of_ones_own_trains_the_official_code_on_its_declared_background(
    tmp_path, code, white
) -> None:
    """A white GS³-format scene of one's own gets the code's white-background flag in every train
    step; the same scene in a benchmark suite keeps the suite's flags (RNG stays black on gs3: the
    paper's setting), and a black scene of one's own gets none."""
    write_gs3_tree(tmp_path / "white", n_train=2, n_test=2, size=(8, 8))
    white_scene = load_scene(tmp_path / "white", format="gs3")
    black_scene = load_scene(write_data(tmp_path / "data") / "Alpha", format="nrhints")
    assert list(white_scene.background) == [1, 1, 1] and list(black_scene.background) == [0, 0, 0]
    settings = CodeSettings(
        method=code.name,
        checkout=str(write_checkout(tmp_path / "checkout", code.name)),
        python=sys.executable,
    )

    def train_commands(scene, suite: str) -> list[list[str]]:
        run = prepare(
            code,
            settings,
            scene,
            tmp_path / "work",
            suite,
            "train",
            "test",
            None,
            OfficialConfig(iterations=40_000),
        )
        return [record.argv for record in run.commands if record.step in code.train_steps]

    def says_white(argv: list[str]) -> bool:
        where = [i for i, arg in enumerate(argv) if arg == white[0]]
        return bool(where) and argv[where[-1] : where[-1] + len(white)] == white

    assert all(says_white(argv) for argv in train_commands(white_scene, "data-gs3"))
    assert not any(says_white(argv) for argv in train_commands(black_scene, "data-nrhints"))
    benchmark = train_commands(white_scene, "gs3")
    assert all(says_white(argv) for argv in benchmark) == (code is not RNG_CODE)
    assert f"train {' '.join(white)}" in " ".join(code.describe())


def test_methods_show_lists_the_scaled_flags_and_the_points_file() -> None:
    lines = SSDGS_CODE.describe()
    scaled = next(line for line in lines if line.startswith("scaled with reference_iterations"))
    assert "--opacity_reset_interval [3000]" in scaled and "--unfreeze_iterations [0]" in scaled
    assert "init_points: written to {scene}/points3d.ply" in lines


@pytest.mark.parametrize(
    ("code", "variable"), [(SSDGS_CODE, "OLATBENCH_SSDGS_CODE"), (GS3_CODE, "OLATBENCH_GS3_CODE")]
)
def test_the_schedule_flags_are_every_iteration_option_of_the_checkouts_parser(
    code, variable
) -> None:
    """Read the pinned checkout's OptimizationParams: every option counted in iterations is scaled,
    at its default (the densification interval, a cadence, excepted)."""
    checkout = os.environ.get(variable)
    if not checkout:
        pytest.skip(
            f"{variable} is not set (a checkout of {code.name}'s repository at its pinned commit)"
        )
    text = (Path(checkout) / "arguments" / "__init__.py").read_text()
    options = text[text.index("class OptimizationParams") :]
    defaults = {
        f"--{m[1]}": int(m[2].replace("_", ""))
        for m in re.finditer(r"self\.(\w+)\s*=\s*([0-9_]+)\s*$", options, re.M)
        if re.search(r"step|iter|interval", m[1])
        and m[1] not in ("iterations", "densification_interval")
    }
    assert {
        k: v for k, v in code.schedule_flags.items() if k != "--unfreeze_iterations"
    } == defaults
    assert (
        'add_argument("--unfreeze_iterations", type=int, default=0)'
        in (Path(checkout) / "train.py").read_text()
    )
    # the Gaussian budget the mini presets set (--maximum_gs)
    assert "self.maximum_gs = 550_000" in text


def test_the_mini_presets_take_the_native_densification_budget_and_position_decay() -> None:
    from olatbench.methods.baselines.gs3_spec import PRESETS as GS3_PRESETS
    from olatbench.methods.registry import get_spec
    from olatbench.methods.ssdgs.presets import SUITE_PRESETS

    for official, native in (
        ("ssdgs-official", SUITE_PRESETS["mini"]),
        ("gs3-official", GS3_PRESETS["mini"]),
    ):
        preset = get_spec(official).presets["mini"]
        args = dict(
            zip(preset["preset_args"][::2], map(int, preset["preset_args"][1::2]), strict=True)
        )
        assert args == {
            "--densify_from_iter": native["densify_from"],
            "--densify_until_iter": native["densify_until"],
            "--opacity_reset_interval": native["opacity_reset_interval"],
            "--position_lr_max_steps": native["position_lr_max_steps"],
            "--maximum_gs": native["max_gaussians"],
        }
        assert (preset["iterations"], preset["reference_iterations"], preset["init_points"]) == (
            native["iterations"],
            native["reference_iterations"],
            native["num_init_gaussians"],
        )
