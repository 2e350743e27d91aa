"""Presets derived from a scene of no suite (`olatbench.methods.scene_presets`,
`bench.plan.derived_preset`), the paper's and the mini suite's configs left exactly as they were,
and ``--resolution`` made explicit (bounded, no silent squashing, part of the job's folder and id
when it differs from the suite's)."""

from __future__ import annotations

import json

import pytest
import test_runner_support as support
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.bench.jobs import config_to_dict, hash_json
from olatbench.bench.plan import PlanError, checked_resolution, make_plan, resolve_config
from olatbench.cli import main
from olatbench.datasets.suites import SUITES
from olatbench.methods.registry import get_spec
from olatbench.methods.scene_presets import SceneFacts, derive_preset

NATIVE = ("3dgs", "gs3", "ssdgs")


def _derive(method: str, facts: SceneFacts, iterations: int | None = None):
    spec = get_spec(method)
    return derive_preset(spec.scene_recipe, spec.presets[spec.scene_recipe], facts, iterations)


@pytest.mark.parametrize("method", NATIVE)
def test_a_scene_the_size_of_the_mini_ones_or_smaller_gets_the_recipe_as_it_is(method):
    spec = get_spec(method)
    # mini; SSD-GS: own-data, mini over the official switches
    recipe = dict(spec.presets[spec.scene_recipe])
    for facts in (SceneFacts(30, 64, 64), SceneFacts(100, 64, 64), SceneFacts(3, 16, 12)):
        derived = _derive(method, facts)
        assert dict(derived.values) == recipe, facts
        assert set(derived.reasons) >= {"iterations", "max_gaussians", "num_init_gaussians"}


def test_ssdgs_own_data_recipe_is_the_mini_recipe_over_the_official_switches():
    """What `--variant mini` gave on a scene of one's own before presets were derived (the format's
    suite preset under mini): the official code's switches, the mini recipe's values, no
    refinement."""
    presets = get_spec("ssdgs").presets
    recipe, mini = presets["own-data"], presets["mini"]
    assert all(recipe[name] == value for name, value in mini.items())
    assert (
        recipe["init_shape"] == "box"
        and recipe["shadow_mode"] == "density"
        and recipe["asg_form"] == "official"
    )
    assert (
        not recipe["refine_camera"]
        and not recipe["refine_light"]
        and recipe["test_pose_fitting"] == "none"
    )


def test_ssdgs_on_a_small_scene_starts_no_100k_gaussians_and_refines_nothing():
    values = resolve_config(
        get_spec("ssdgs"), SUITES["nrhints"], derived=_derive("ssdgs", SceneFacts(30, 64, 64))
    )
    paper = resolve_config(get_spec("ssdgs"), SUITES["nrhints"])
    assert (
        paper.num_init_gaussians == 100_000
        and paper.refine_camera
        and paper.test_pose_fitting == "interleaved"
    )
    assert (
        values.num_init_gaussians == 2_000
        and values.max_gaussians == 5_000
        and values.iterations == 3_000
    )
    assert (
        not values.refine_camera and not values.refine_light and values.test_pose_fitting == "none"
    )


def test_larger_scenes_scale_length_budget_and_light_view_within_the_papers_bounds():
    # 32× the mini pixel count, 8× its side
    facts = SceneFacts(train_images=1_000, width=512, height=256)
    ssdgs = _derive("ssdgs", facts)
    assert ssdgs.values["iterations"] == 30_000  # 3000 steps per 100 images
    assert (
        ssdgs.values["max_gaussians"] == 5_000 * 32
        and ssdgs.values["num_init_gaussians"] == 2_000 * 32
    )
    assert ssdgs.values["shadow_resolution"] == 96 * 8
    big = _derive("3dgs", SceneFacts(train_images=100_000, width=1024, height=1024))
    # the paper's caps
    assert big.values["iterations"] == 100_000 and big.values["max_gaussians"] == 550_000
    assert big.values["num_init_gaussians"] == round(2_000 * 550_000 / 12_000)
    asked = _derive("gs3", facts, iterations=200)
    assert asked.values["iterations"] == 200 and asked.reasons["iterations"] == "as asked"


def test_the_paper_and_mini_suites_resolve_exactly_the_configs_they_did():
    """Pinned at the commit before presets were derived (ce86046): any change here changes the
    paper's runs."""
    before = {
        "3dgs/mini": "560101d8145b9db7",
        "3dgs/nrhints": "45363e27404c641b",
        "3dgs/gs3": "45363e27404c641b",
        "3dgs/sssgs": "daf0ff331c953bca",
        "gs3/mini": "8193ab3d90681b01",
        "gs3/nrhints": "986e28f7a3dbb3f9",
        "gs3/gs3": "986e28f7a3dbb3f9",
        "gs3/sssgs": "f454cb5c470aff7b",
        "ssdgs/mini": "6f8b66a8ab3d73ea",
        "ssdgs/nrhints": "bf38f10786d5f7fa",
        "ssdgs/gs3": "7b5eb3ba20257039",
        "ssdgs/sssgs": "41a38367d0eac679",
    }
    # fields added since, each at the value that keeps the old behaviour (#45: the recorded light
    # intensity; #53: SSD-GS's official SSS widths, GS³'s light-view framing and mode, now shared
    # with SSD-GS; the parity harness's shadow-network bias, term-start counting and GS³'s
    # tiny-cuda-nn network layout)
    added_since = {"light_intensity": "recorded"}
    added_to = {
        "ssdgs": {
            "sss_last_hidden": None,
            "shadow_input_bias": "vector",
            "schedule_counting": "zero_based",
        },
        "gs3": {"shadow_framing": "scene", "shadow_mode": "uniform", "network_layout": "torch"},
    }
    # fields added since that change the old behaviour on purpose: GS³'s bound on its start's
    # brightness under recorded intensities (docs/baselines.md, "Brightness at the start"; None
    # would keep the old start)
    changed_since = {"gs3": {"initial_shading": 0.5}}
    now = {}
    for method in NATIVE:
        for suite in ("mini", "nrhints", "gs3", "sssgs"):
            config = config_to_dict(resolve_config(get_spec(method), SUITES[suite]))
            for name, old_behaviour in {**added_since, **added_to.get(method, {})}.items():
                assert config.pop(name, old_behaviour) == old_behaviour, (method, suite, name)
            for name, value in changed_since.get(method, {}).items():
                assert config.pop(name) == value, (method, suite, name)
            now[f"{method}/{suite}"] = hash_json(config)[:16]
    assert now == before


def test_a_suites_jobs_keep_their_config_and_identity_layout(tmp_path):
    """The plan of a suite's scene (a data root, no scene_paths) applies the suite's preset, not a
    derived one, and without --resolution names no resolution: the mini suite's folders and
    identities are laid out as before."""
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    suite = support.tiny_suite(scenes=("Alpha",))
    (job,) = make_plan("3dgs", suite, tmp_path / "runs", data_root=data, progress=False)
    assert (
        job.config == config_to_dict(resolve_config(get_spec("3dgs"), suite)) and job.derived == {}
    )
    assert job.variant == "default" and job.resolution is None
    assert sorted(job.identity()) == sorted(
        [
            "schema",
            "method",
            "config",
            "suite",
            "scene",
            "variant",
            "seed",
            "colourspace",
            "resolution",
            "splits",
            "data_manifest",
            "protocol",
            "code",
            *(["frame"] if suite.frame != "dataset" else []),
        ]
    )


def test_resolution_is_bounded_and_keeps_the_aspect_ratio_unless_asked():
    assert checked_resolution(None, (64, 48), "s") is None
    assert checked_resolution((32, 24), (64, 48), "s") == (32, 24)
    # a pixel's rounding is no squashing
    assert checked_resolution((33, 24), (64, 48), "s") == (33, 24)
    with pytest.raises(PlanError, match=r"aspect ratio of scene s \(64x48\).*--stretch"):
        checked_resolution((50, 30), (64, 48), "s")
    assert checked_resolution((50, 30), (64, 48), "s", stretch=True) == (50, 30)
    with pytest.raises(PlanError, match=r"larger than the images of scene s \(64x48\).*--upscale"):
        checked_resolution((128, 96), (64, 48), "s")
    assert checked_resolution((128, 96), (64, 48), "s", upscale=True) == (128, 96)
    for native in ((64, 48), None):  # absurd sizes are refused even before the data exists
        with pytest.raises(PlanError, match="100000 pixels is outside 1 to 16384"):
            checked_resolution((100_000, 100_000), native, "s", stretch=True, upscale=True)


def _plan(*args) -> list[dict]:
    result = CliRunner().invoke(main, ["run", *map(str, args), "--dry-run", "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def test_own_scenes_train_at_their_own_size_and_two_sizes_live_side_by_side(tmp_path):
    scene = tmp_path / "Cup"
    write_nrhints_tree(scene, n_train=3, n_test=1, size=(32, 24))
    out = tmp_path / "runs"
    (native,) = _plan("-m", "3dgs", "--data", scene, "-o", out)
    assert (
        native["resolution"] == "native"
        and native["folder"] == "data-nrhints/3dgs/default/Cup/seed0"
    )
    (same,) = _plan("-m", "3dgs", "--data", scene, "-o", out, "--resolution", "32x24")
    assert same["id"] == native["id"]  # asking for the scene's own size is the same job
    (half,) = _plan("-m", "3dgs", "--data", scene, "-o", out, "--resolution", "16x12")
    assert half["resolution"] == [16, 12] and half["id"] != native["id"]
    assert half["folder"] == "data-nrhints/3dgs/default~resolution=16x12/Cup/seed0"
    (both,) = _plan(
        "-m", "3dgs", "--data", scene, "-o", out, "--resolution", "16x12", "--iterations", "9"
    )
    assert both["variant"] == "default~iterations=9,resolution=16x12"
    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "3dgs",
            "--data",
            str(scene),
            "-o",
            str(out),
            "--dry-run",
            "--resolution",
            "20x10",
        ],
    )
    assert result.exit_code == 2 and "--stretch" in result.output
    text = (
        CliRunner()
        .invoke(main, ["run", "-m", "ssdgs", "--data", str(scene), "-o", str(out), "--dry-run"])
        .output
    )
    assert "16x12" not in text and "native" in text
    assert (
        "preset derived from the scene" in text
        and "max_gaussians = 5000: the own-data recipe's 5000" in text
    )


def test_a_suites_resolution_other_than_its_own_names_the_variant(tmp_path):
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",), size=(64, 48))
    suite = support.tiny_suite(scenes=("Alpha",))
    (own,) = make_plan("trivial", suite, tmp_path / "runs", data_root=data, progress=False)
    (half,) = make_plan(
        "trivial", suite, tmp_path / "runs", data_root=data, progress=False, resolution=(32, 24)
    )
    assert (
        own.variant == "default"
        and half.variant == "default~resolution=32x24"
        and own.folder != half.folder
    )
    with pytest.raises(PlanError, match="aspect ratio"):
        make_plan(
            "trivial", suite, tmp_path / "runs", data_root=data, progress=False, resolution=(32, 32)
        )


def test_methods_show_data_prints_the_derived_values_and_why(tmp_path):
    scene = tmp_path / "Cup"
    write_nrhints_tree(scene, n_train=3, n_test=1, size=(32, 24))
    result = CliRunner().invoke(main, ["methods", "show", "ssdgs", "--data", str(scene)])
    assert result.exit_code == 0, result.output
    assert f"preset derived from {scene}" in result.output
    assert "num_init_gaussians = 2000: the own-data recipe's share of the budget" in result.output
    assert "refine_camera = false: off" in result.output
    data = json.loads(
        CliRunner()
        .invoke(
            main, ["methods", "show", "3dgs", "--data", str(scene), "--iterations", "200", "--json"]
        )
        .output
    )
    assert data["derived"]["iterations"] == {"value": 200, "why": "as asked"}
