"""The one config resolver (`olatbench.methods.resolve`): every built-in method × suite × variant
resolves to the config the planner gave before it existed (`tests/data/resolved_configs.json.gz`,
written by `tests/config_cases.py` at e0bac5b), and each field names its source."""

from __future__ import annotations

from pathlib import Path

import pytest
from config_cases import cases, read

from olatbench.bench.plan import resolve_sources
from olatbench.datasets.suites import SUITES
from olatbench.methods.registry import get_spec

BASELINE = Path(__file__).parent / "data" / "resolved_configs.json.gz"
NEW_VARIANTS = ("official",)  # variants added since the baseline: not in it


def _new(key: str) -> bool:
    return any(f"|{name}" in key for name in NEW_VARIANTS)


def test_every_plan_resolves_to_the_baseline_config() -> None:
    before, now = read(str(BASELINE)), cases()
    assert sorted(before) == sorted(key for key in now if not _new(key))
    for key, outcome in before.items():
        if key.endswith("|defaults"):  # fields added since keep the old ones' defaults
            assert {name: now[key]["config"][name] for name in outcome["config"]} == outcome[
                "config"
            ], key
        else:
            assert now[key] == outcome, key


def test_sources_name_each_layer() -> None:
    spec = get_spec("ssdgs")
    resolved = resolve_sources(spec, SUITES["mini"], "mini+ablation-C", overrides={"num_asg": 2})
    sources = resolved.sources
    assert sources["num_asg"] == "--set" and resolved.config.num_asg == 2
    assert sources["use_shadow"] == "variant ablation-C"
    # the variant's preset wins over the suite's equal value
    assert sources["iterations"] == "variant mini"
    assert sources["shadow_framing"] == "variant mini"
    assert sources["dipole_eta"] == "default"
    assert set(sources) == {name for name, _, _ in resolved.rows()}
    plain = resolve_sources(spec, SUITES["nrhints"]).sources
    assert plain["refine_camera"] == "suite preset nrhints" and plain["use_sss"] == "default"


def test_a_scene_of_no_suite_names_its_recipe_and_what_was_derived() -> None:
    from dataclasses import replace

    from olatbench.bench.plan import derived_preset
    from olatbench.methods.scene_presets import SceneFacts

    spec = get_spec("ssdgs")
    suite = replace(
        SUITES["nrhints"], name="own", scene_paths={"scene": "/nowhere"}, method_preset="nrhints"
    )
    derived = derived_preset(spec, suite, SceneFacts(300, 128, 128))
    sources = resolve_sources(spec, suite, "ablation-C", derived=derived).sources
    assert sources["iterations"] == sources["max_gaussians"] == "derived from the scene"
    assert (
        sources["asg_form"] == "scene recipe own-data"
        and sources["use_sss"] == "variant ablation-C"
    )


def test_a_spec_that_fixes_its_length_is_named() -> None:
    from olatbench.methods.spec import MethodSpec

    spec = MethodSpec(
        name="fixed",
        description="",
        implementation="a:B",
        iterations=7,
        config="olatbench.methods.gaussian_config:GaussianConfig",
    )
    resolved = resolve_sources(spec, SUITES["gs3"])
    assert (resolved.config.iterations, resolved.sources["iterations"]) == (7, "method spec")
    assert (
        resolve_sources(get_spec("nrhints-official"), SUITES["mini"]).sources["iterations"]
        == "suite mini"
    )
    assert (
        resolve_sources(get_spec("3dgs"), SUITES["gs3"]).sources["iterations"] == "suite preset gs3"
    )
    assert (
        resolve_sources(get_spec("3dgs"), SUITES["gs3"], overrides={"iterations": 9}).sources[
            "iterations"
        ]
        == "--set"
    )


@pytest.mark.parametrize("method", ["ssdgs", "gs3", "3dgs"])
def test_method_and_spec_resolve_the_same_with_sources(method: str) -> None:
    spec = get_spec(method)
    resolved = spec.resolve_sources("mini", {"iterations": 9}, "job.json")
    assert resolved.config == spec.resolve_config("mini", iterations=9)
    assert resolved.sources["iterations"] == "job.json"


def test_dry_run_and_methods_show_print_the_sources(tmp_path) -> None:
    import json

    from click.testing import CliRunner

    from olatbench.cli import main

    args = [
        "run",
        "-m",
        "ssdgs",
        "-s",
        "mini",
        "--scenes",
        "aniso_metal",
        "--variant",
        "ablation-C",
        "--set",
        "num_asg=2",
        "--dry-run",
        "-o",
        str(tmp_path / "runs"),
    ]
    text = CliRunner().invoke(main, args)
    assert text.exit_code == 0, text.output
    assert (
        "--set: num_asg" in text.output
        and "variant ablation-C: use_shadow, use_sss, use_specular" in text.output
    )
    data = json.loads(CliRunner().invoke(main, [*args, "--json"]).output)
    (job,) = data["jobs"] if isinstance(data, dict) else data
    assert (
        job["sources"]["num_asg"] == "--set"
        and job["sources"]["mlp_lr_init"] == "suite preset mini"
    )
    assert set(job["sources"]) == set(job["config"])
    shown = CliRunner().invoke(
        main, ["methods", "show", "ssdgs", "--suite", "mini", "--variant", "ablation-C", "--json"]
    )
    fields = {entry["name"]: entry for entry in json.loads(shown.output)["config"]}
    assert (fields["use_sss"]["value"], fields["use_sss"]["source"]) == (True, "variant ablation-C")
    assert (
        fields["num_asg"]["value"],
        fields["num_asg"]["default"],
        fields["num_asg"]["source"],
    ) == (4, 8, "suite preset mini")


def test_one_scaling_rule_moves_no_step_of_any_plan() -> None:
    """`scaled_steps` replaced two formulas (``round(v * it / ref)`` in `GaussianConfig.steps`,
    ``round(v * (it / ref))`` in `Schedule.scaled` and the official runner, which alone kept
    positive values >= 1): on every resolved config of the baseline, every iteration-valued field
    and schedule threshold lands where the old formula put it."""
    from olatbench.methods.run_length import scaled_steps
    from olatbench.methods.ssdgs.schedule import SCHEDULES

    thresholds = {
        v
        for s in SCHEDULES.values()
        for v in (*s.enable.values(), s.refine_camera_from, s.refine_light_from)
    }
    thresholds |= {
        v for s in SCHEDULES.values() for windows in s.frozen.values() for w in windows for v in w
    }
    checked = 0
    for key, outcome in read(str(BASELINE)).items():
        method = key.split("|")[0]
        spec = get_spec(method)
        if "config" not in outcome or key.endswith("|defaults") or spec.kind == "official":
            continue
        config = spec.resolve_config(None, **outcome["config"])
        it, ref = config.iterations, config.reference_iterations
        for name in type(config).iteration_fields:
            value = getattr(config, name)
            if value is not None:
                assert scaled_steps(value, it, ref) == round(value * it / ref), (key, name)
                checked += 1
        if method == "ssdgs":
            for value in thresholds:
                assert scaled_steps(value, it, ref) == round(value * (it / ref)), (key, value)
    assert checked > 1000
