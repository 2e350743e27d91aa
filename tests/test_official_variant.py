"""The official-parity variant (`--variant official`, from `olatbench.methods.authors` data) and
`methods diff`: the variant takes the authors' value of every field with a counterpart over any
suite's run settings, its iteration counts land on the steps the official runner gives the authors'
flags (one rule, `olatbench.methods.run_length.scaled_steps`), every departure of a preset is
recorded with a reason, and the tables in the docs are the command's."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from olatbench.bench.plan import resolve_sources
from olatbench.cli import main
from olatbench.datasets.suites import SUITES
from olatbench.methods.authors import OFFICIAL_VARIANT, departures
from olatbench.methods.official.specs import GS3_CODE, SSDGS_CODE
from olatbench.methods.registry import get_spec

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("ssdgs", "gs3")


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("suite", sorted(SUITES))
def test_the_official_variant_departs_from_the_authors_nowhere(method: str, suite: str) -> None:
    spec = get_spec(method)
    resolved = resolve_sources(spec, SUITES[suite], OFFICIAL_VARIANT)
    assert departures(resolved, spec.load_authors()) == []
    plain = resolve_sources(spec, SUITES[suite])
    for name in spec.load_authors().suite_fields:  # the suite's run settings are kept
        assert getattr(resolved.config, name) == getattr(plain.config, name), name


@pytest.mark.parametrize("method", METHODS)
def test_every_departure_of_the_defaults_mini_and_the_grids_has_a_reason(method: str) -> None:
    spec = get_spec(method)
    for variant in (
        "default",
        "mini",
        *(f"mini+{name}" for grid in spec.ablations.values() for name in grid if name != "default"),
    ):
        rows = departures(spec.resolve_sources(variant), spec.load_authors())
        assert rows, variant
        assert [row.name for row in rows if row.departure is None] == [], variant


def test_methods_show_official_names_the_lobes_form_and_trained_sigma_with_their_source() -> None:
    shown = CliRunner().invoke(
        main, ["methods", "show", "ssdgs", "--suite", "mini", "--variant", "official"]
    )
    assert shown.exit_code == 0, shown.output
    rows = {
        line.split()[0]: line.split() for line in shown.output.splitlines() if line.startswith("  ")
    }
    assert rows["num_asg"][2:] == ["8", "variant", "official"]
    assert rows["asg_form"][2:] == ["'official'", "variant", "official"]
    assert rows["asg_freeze_sigma"][2:] == ["False", "variant", "official"]
    assert rows["iterations"][2:] == ["3000", "suite", "preset", "mini"]


# The authors' flag -> the native field or schedule threshold it sets
# (both at the reference length).
_FIELDS = {
    "--asg_lr_freeze_step": "asg_lr_decay_from",
    "--asg_lr_max_steps": "asg_lr_max_steps",
    "--freeze_phasefunc_steps": "mlp_lr_decay_from",
    "--neural_phasefunc_lr_max_steps": "mlp_lr_max_steps",
    "--scatter_lr_freeze_step": "mlp_lr_decay_from",
    "--scatter_lr_max_steps": "mlp_lr_max_steps",
    "--train_cam_freeze_step": "refine_camera_from",
    "--train_pl_freeze_step": "refine_light_from",
    "--opt_cam_lr_delay_step": "camera_lr_delay_steps",
    "--opt_pl_lr_delay_step": "light_lr_delay_steps",
    "--opt_cam_lr_max_steps": "refinement_lr_max_steps",
    "--position_lr_max_steps": "position_lr_max_steps",
    "--densify_until_iter": "densify_until",
    "--densify_from_iter": "densify_from",
    "--opacity_reset_interval": "opacity_reset_interval",
}


def _flag(argv: list[str], flag: str) -> int:
    return int(argv[max(i for i, arg in enumerate(argv) if arg == flag) + 1])


@pytest.mark.parametrize("iterations", [200, 1234, 3000, 7777])
def test_the_official_variant_and_the_official_runner_compress_to_the_same_steps(
    iterations: int,
) -> None:
    spec, official = get_spec("ssdgs"), get_spec("ssdgs-official")
    config = resolve_sources(
        spec, SUITES["mini"], OFFICIAL_VARIANT, overrides={"iterations": iterations}
    ).config
    runner = official.resolve_config("mini", iterations=iterations)
    assert runner.reference_iterations == config.reference_iterations
    values = {"scene": "/s", "model": "/m", "checkout": "/c", "iterations": iterations}
    argv = SSDGS_CODE.command(
        "train",
        SSDGS_CODE.commands[0][1],
        values,
        "mini",
        scene="x",
        schedule_lengths=(iterations, runner.reference_iterations),
        preset_args=runner.preset_args,
    )
    for flag, name in _FIELDS.items():
        assert _flag(argv, flag) == config.steps(getattr(config, name)), flag
    schedule, starts = config.resolved_schedule(), config.refinement_starts()
    # train.py:131-133 counts iterations from 1: shadow on after iteration unfreeze_iterations
    # (our step unfreeze_iterations), SSS on at iteration scatter_warmup_step (our step
    # scatter_warmup_step - 1)
    assert _flag(argv, "--unfreeze_iterations") == schedule.enable["shadow"]
    assert _flag(argv, "--scatter_warmup_step") - 1 == schedule.enable["sss"]
    assert _flag(argv, "--asg_freeze_step") == schedule.frozen["asg_lobes"][0][1]
    assert (
        _flag(argv, "--scatter_freeze_step"),
        _flag(argv, "--scatter_unfreeze_step"),
    ) == schedule.frozen["sss_mlp"][0]
    assert _flag(argv, "--specular_freeze_step") == schedule.frozen["shadow_mlp"][0][0]
    # specular on at iteration specular_freeze_step + fit_linear_step (our step one less): two flags
    # rounded apart, one threshold here
    total = _flag(argv, "--specular_freeze_step") + _flag(argv, "--fit_linear_step")
    assert abs(total - 1 - schedule.enable["specular"]) <= 1
    assert (starts["camera"], starts["light"]) == (
        _flag(argv, "--train_cam_freeze_step"),
        _flag(argv, "--train_pl_freeze_step"),
    )
    gs3 = resolve_sources(
        get_spec("gs3"), SUITES["mini"], OFFICIAL_VARIANT, overrides={"iterations": iterations}
    )
    gs3_argv = GS3_CODE.command(
        "train",
        GS3_CODE.commands[0][1],
        values,
        "mini",
        scene="x",
        schedule_lengths=(iterations, gs3.config.reference_iterations),
    )
    cfg = gs3.config
    assert _flag(gs3_argv, "--unfreeze_iterations") == cfg.steps(cfg.shadow_from)
    assert _flag(gs3_argv, "--spcular_freeze_step") == cfg.steps(cfg.mlp_freeze_from)
    assert _flag(gs3_argv, "--asg_freeze_step") == cfg.steps(cfg.asg_lobes_from)
    assert _flag(gs3_argv, "--asg_lr_freeze_step") == cfg.steps(cfg.asg_lr_decay_from)
    assert _flag(gs3_argv, "--asg_lr_max_steps") == cfg.steps(cfg.asg_lr_max_steps)


def test_the_sss_network_takes_the_official_widths() -> None:
    torch = pytest.importorskip("torch")
    from olatbench.methods.shading.mlp import mlp

    torch.manual_seed(0)
    plain = mlp(10, 16, 3, 4)
    torch.manual_seed(0)
    layers = [
        torch.nn.Linear(10, 16),
        torch.nn.ReLU(),
        torch.nn.Linear(16, 16),
        torch.nn.ReLU(),
        torch.nn.Linear(16, 16),
        torch.nn.ReLU(),
        torch.nn.Linear(16, 3),
    ]
    before = torch.nn.Sequential(*layers)  # what mlp built before last_hidden existed
    assert all(
        torch.equal(a, b)
        for a, b in zip(plain.state_dict().values(), before.state_dict().values(), strict=True)
    )
    widths = [
        layer.out_features
        for layer in mlp(10, 256, 3, 5, last_hidden=128)
        if hasattr(layer, "out_features")
    ]
    assert widths == [256, 256, 256, 128, 3]


DOC_BLOCK = re.compile(r"<!-- olatbench (methods diff [^>]*?) -->\n(.*?)\n<!-- end -->", re.S)


@pytest.mark.parametrize("doc", ["docs/ssdgs.md", "docs/baselines.md"])
def test_the_docs_embed_the_generated_diff_tables(doc: str) -> None:
    blocks = DOC_BLOCK.findall((ROOT / doc).read_text())
    assert blocks, f"{doc} embeds no methods diff table"
    for command, text in blocks:
        result = CliRunner().invoke(main, [*command.split(), "--markdown"])
        assert result.exit_code == 0, result.output
        assert text == result.output.rstrip("\n"), (
            f"{doc}: regenerate with olatbench {command} --markdown"
        )
