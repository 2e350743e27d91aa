"""`--set KEY=VALUE`: every value fitted to its config field's type, or one error naming field,
value and form."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import pytest
from click.testing import CliRunner

from olatbench.bench.plan import PlanError, make_plan, parse_overrides
from olatbench.methods.overrides import OverrideError, check_overrides


@dataclass
class Config:
    flag: bool = True
    count: int = 1
    rate: float = 0.1
    name: str = "a"
    mode: Literal["fast", "exact"] = "fast"
    colour: tuple[float, float, float] | None = None
    sizes: tuple[int, ...] = (1,)
    cap: int | None = None


def fit(**values):
    return check_overrides(Config, values, "demo")


def test_values_are_fitted_to_their_field_types():
    parsed = parse_overrides(
        [
            "flag=False",
            "count=5e3",
            "rate=1",
            "name=123",
            "mode=exact",
            "colour=[1, 0.5, 0]",
            "sizes=[2, 3]",
            "cap=null",
        ]
    )
    checked = fit(**parsed)
    assert checked == {
        "flag": False,
        "count": 5000,
        "rate": 1.0,
        "name": "123",
        "mode": "exact",
        "colour": (1.0, 0.5, 0.0),
        "sizes": (2, 3),
        "cap": None,
    }
    assert type(checked["rate"]) is float and type(checked["count"]) is int
    assert fit(flag="TRUE", cap="none", name="density") == {
        "flag": True,
        "cap": None,
        "name": "density",
    }


@pytest.mark.parametrize(
    ("field", "text", "form"),
    [
        ("flag", "maybe", "true or false"),
        ("flag", "1", "true or false"),
        ("count", "2.5", "a whole number"),
        ("count", "true", "a whole number"),
        ("rate", "fast", "a number"),
        ("mode", "slow", "one of fast, exact"),
        ("colour", "[1, 2]", "a list of 3 values"),
        ("sizes", "[1, 2.5]", "a list of a whole number values"),
        ("cap", "lots", "a whole number or null"),
    ],
)
def test_values_that_do_not_fit_are_one_error_naming_field_value_and_form(field, text, form):
    with pytest.raises(OverrideError) as error:
        fit(**parse_overrides([f"{field}={text}"]))
    message = str(error.value)
    assert (
        message.startswith(f"--set {field}={text}: field '{field}' of method 'demo' takes")
        and form in message
    )


def test_unknown_fields_are_named():
    with pytest.raises(
        OverrideError, match=r"method 'demo' has no config field nope; its fields: .*count"
    ):
        fit(nope=1)


def test_set_use_sss_false_plans_a_job_with_sss_off_and_maybe_is_refused(tmp_path):
    pytest.importorskip("olatbench.methods.ssdgs.config")
    job = make_plan(
        "ssdgs",
        "mini",
        tmp_path,
        scenes=["diffuse_shadow"],
        generate=False,
        progress=False,
        overrides=parse_overrides(["use_sss=False"]),
    )[0]
    assert job.config["use_sss"] is False and job.variant == "default~use_sss=false"
    with pytest.raises(
        PlanError,
        match=r"--set use_sss=maybe: field 'use_sss' of method 'ssdgs' takes true or false",
    ):
        make_plan(
            "ssdgs",
            "mini",
            tmp_path,
            generate=False,
            progress=False,
            overrides={"use_sss": "maybe"},
        )


def test_cli_reports_a_misfit_as_one_line_without_a_traceback(tmp_path):
    from olatbench.cli import main

    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "ssdgs",
            "-s",
            "mini",
            "--dry-run",
            "-o",
            str(tmp_path),
            "--set",
            "num_asg=many",
        ],
    )
    assert result.exit_code == 2 and "Traceback" not in result.output  # a usage error
    assert (
        "--set num_asg=many: field 'num_asg' of method 'ssdgs' takes a whole number"
        in result.output
    )


@pytest.mark.parametrize("text", ["NaN", "Infinity", "-Infinity", "1e999", "[1, NaN]"])
def test_numbers_that_are_not_finite_are_refused_when_read(text):
    """json.loads reads NaN, Infinity and 1e999 (as inf) as floats: no config value, and no
    results.json holds them."""
    with pytest.raises(PlanError, match=r"--set rate=.*is not a finite number"):
        parse_overrides([f"rate={text}"])
    with pytest.raises(OverrideError, match="takes a finite number"):
        fit(rate=float("nan"))  # from Python, past the parser


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("position_lr_init=-0.1", "field 'position_lr_init' of method 'ssdgs' must be ≥ 0"),
        ("num_asg=0", "field 'num_asg' of method 'ssdgs' must be ≥ 1"),
        ("lambda_dssim=1.5", "field 'lambda_dssim' of method 'ssdgs' must be in [0, 1]"),
        ("init_opacity=1", "field 'init_opacity' of method 'ssdgs' must be in (0, 1)"),
        ("background=[0, 2, 0]", "field 'background' of method 'ssdgs' must be in [0, 1]"),
        ("position_lr_init=NaN", "NaN is not a finite number"),
        ("position_lr_init=1e999", "1e999 is not a finite number"),
    ],
)
def test_cli_refuses_out_of_range_and_non_finite_values_at_plan_time_with_exit_2(
    tmp_path, setting, message
):
    from olatbench.cli import main

    result = CliRunner().invoke(
        main,
        ["run", "-m", "ssdgs", "-s", "mini", "--dry-run", "-o", str(tmp_path), "--set", setting],
    )
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output
    assert result.output.count("Error:") == 1


def test_ranges_hold_for_every_preset_and_in_range_values_pass(tmp_path):
    """The declared ranges are checked whenever a config is made; every method's presets respect
    them."""
    from olatbench.datasets.suites import SUITES
    from olatbench.methods.ranges import check_ranges
    from olatbench.methods.registry import builtin_specs, config_class

    checked = 0
    for spec in builtin_specs().values():
        config_type = config_class(spec)
        for name, preset in spec.presets.items():
            try:
                config = config_type(**preset)
            # a cross-field rule (e.g. test-time refinement needs refinement on)
            except ValueError as error:
                assert "must be ≥" not in str(error) and "must be in" not in str(error), (
                    spec.name,
                    name,
                    error,
                )
                continue
            check_ranges(config, spec.name)
            checked += 1
    assert checked > 20
    job = make_plan(
        "ssdgs",
        SUITES["mini"],
        tmp_path,
        scenes=["diffuse_shadow"],
        generate=False,
        progress=False,
        overrides=parse_overrides(["position_lr_init=0", "lambda_dssim=1"]),
    )[0]
    assert job.config["position_lr_init"] == 0.0 and job.config["lambda_dssim"] == 1.0
    from olatbench.methods.ssdgs.config import SSDGSConfig

    with pytest.raises(ValueError, match=r"SSD-GS config: mlp_lr_init must be ≥ 0, got -1"):
        SSDGSConfig(mlp_lr_init=-1.0)  # presets and job.json files go through the same check
