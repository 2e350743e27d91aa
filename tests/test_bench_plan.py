"""Plans: variant and ablation grids, config resolution order, scenes, data roots."""

from __future__ import annotations

import dataclasses

import pytest
import test_runner_support as support

from olatbench.bench.plan import (
    PlanError,
    expand_variants,
    make_plan,
    resolve_config,
    resolve_data_root,
    resolve_scenes,
)
from olatbench.bench.store import job_folder
from olatbench.methods.registry import get_spec

Trivial = get_spec("trivial")  # the spec of support.TrivialMethod (registered as a class)


def test_ablation_grids_expand_to_the_papers_presets():
    assert expand_variants(Trivial, ablation="components") == [f"ablation-{x}" for x in "ABCDEF"]
    assert expand_variants(Trivial, ablation="schedule") == [f"schedule-{x}" for x in "HIJK"]
    assert expand_variants(Trivial, ablation="shadow-on-sss") == ["default", "shadow-on-sss"]
    assert expand_variants(Trivial) == ["default"]
    assert expand_variants(Trivial, ["ablation-D", "default"], "components")[:2] == [
        "ablation-D",
        "default",
    ]
    assert len(expand_variants(Trivial, ["ablation-D"], "components")) == 6  # deduplicated
    assert set(get_spec("ssdgs").ablations) == {"components", "schedule", "shadow-on-sss"}
    assert tuple(get_spec("ssdgs").ablations["components"]) == tuple(
        Trivial.ablations["components"]
    )


def test_unknown_variant_or_ablation_is_one_clear_error():
    with pytest.raises(PlanError, match=r"no preset nope; its presets: .*ablation-A"):
        expand_variants(Trivial, ["nope"])
    with pytest.raises(
        PlanError,
        match=r"method 'trivial' has no ablation grid 'lighting'; its grids: components, "
        r"schedule, shadow-on-sss",
    ):
        expand_variants(Trivial, ablation="lighting")


def test_config_resolution_order():
    suite = support.tiny_suite(name="other", iterations=33)
    assert resolve_config(Trivial, suite).iterations == 33  # the suite's iteration count
    tiny = support.tiny_suite(name="tiny", iterations=33)
    # the method's preset named after the suite wins
    assert resolve_config(Trivial, tiny).iterations == 12
    config = resolve_config(Trivial, tiny, "ablation-C")
    # variant on top of the suite preset
    assert (config.iterations, config.lr) == (12, pytest.approx(0.03))
    # overrides last
    assert resolve_config(Trivial, tiny, "ablation-C", iterations=5).iterations == 5
    combined = resolve_config(Trivial, tiny, "ablation-C+schedule-I")
    assert (combined.lr, combined.noise) == (pytest.approx(0.03), pytest.approx(0.002))
    assert expand_variants(Trivial, ["ablation-C+schedule-I"]) == ["ablation-C+schedule-I"]
    with pytest.raises(PlanError, match="no preset schedule-Z"):
        expand_variants(Trivial, ["ablation-C+schedule-Z"])


def test_ablation_plan_has_one_job_per_scene_variant_and_seed(tmp_path):
    data = support.write_tiny_data(tmp_path / "data")
    jobs = make_plan(
        "trivial",
        support.tiny_suite(name="x"),
        tmp_path / "runs",
        ablation="components",
        seeds=2,
        data_root=data,
        progress=False,
    )
    assert len(jobs) == 2 * 6 * 2
    assert len({job.id for job in jobs}) == len(jobs)
    job = jobs[7]
    assert (job.scene, job.variant, job.seed) == ("Alpha", "ablation-D", 1)
    assert job.config["lr"] == pytest.approx(0.04)
    assert job.folder == str(
        job_folder(tmp_path / "runs", "x", "trivial", "ablation-D", "Alpha", 1)
    )
    assert job.folder.endswith("x/trivial/ablation-D/Alpha/seed1")


def test_scenes_accept_aliases_and_reject_unknown_names():
    suite = support.tiny_suite()
    assert resolve_scenes(suite, ["beta", "Alpha", "Beta"]) == ["Beta", "Alpha"]
    assert resolve_scenes(suite) == ["Alpha", "Beta"]
    with pytest.raises(PlanError, match="no scene 'Gamma'; scenes: Alpha, Beta"):
        resolve_scenes(suite, ["Gamma"])


def test_missing_data_root_suggests_the_download(monkeypatch):
    monkeypatch.delenv("OLATBENCH_DATA", raising=False)
    with pytest.raises(PlanError, match=r"--data-root or set OLATBENCH_DATA.*datasets download"):
        resolve_data_root(support.tiny_suite(), None, ["Alpha"])


def test_generator_suites_create_their_data_once(tmp_path, monkeypatch):
    calls = []

    def generate(root, progress=True, scenes=None):
        calls.append((root, scenes))
        return support.write_tiny_data(tmp_path / "generated")

    monkeypatch.setattr(support, "fake_generator", generate, raising=False)
    suite = dataclasses.replace(
        support.tiny_suite(), generator="test_runner_support:fake_generator"
    )
    # dry runs never generate
    assert resolve_data_root(suite, None, ["Alpha"], generate=False) is None
    assert calls == []
    assert resolve_data_root(suite, None, ["Alpha"]) == tmp_path / "generated"
    assert resolve_data_root(suite, tmp_path / "generated", ["Alpha"]) == tmp_path / "generated"
    assert calls == [(None, ["Alpha"])]  # only the requested scenes; present data is used as is


def test_dry_run_finds_generated_data_in_the_generators_default_folder(tmp_path, monkeypatch):
    data = support.write_tiny_data(tmp_path / "cache")
    monkeypatch.setattr(
        support, "fake_generator", lambda root, progress=True, scenes=None: 1 / 0, raising=False
    )
    monkeypatch.setattr(support, "fake_generator_root", lambda: data, raising=False)
    suite = dataclasses.replace(
        support.tiny_suite(),
        generator="test_runner_support:fake_generator",
        generator_root="test_runner_support:fake_generator_root",
    )
    # found, nothing generated
    assert resolve_data_root(suite, None, ["Alpha"], generate=False) == data
    jobs = make_plan("trivial", suite, tmp_path / "runs", generate=False, progress=False)
    assert all(job.id and job.data_manifest for job in jobs)  # ids, as a real run on that data has
    assert [job.id for job in jobs] == [
        job.id
        for job in make_plan("trivial", suite, tmp_path / "runs", data_root=data, progress=False)
    ]
    monkeypatch.setattr(support, "fake_generator_root", lambda: tmp_path / "empty", raising=False)
    assert resolve_data_root(suite, None, ["Alpha"], generate=False) is None


def test_dry_plan_without_data_has_no_ids(tmp_path, monkeypatch):
    monkeypatch.setattr(
        support, "fake_generator", lambda root, progress=True, scenes=None: 1 / 0, raising=False
    )
    suite = dataclasses.replace(
        support.tiny_suite(), generator="test_runner_support:fake_generator"
    )
    jobs = make_plan("trivial", suite, tmp_path, generate=False, progress=False)
    assert [job.id for job in jobs] == ["", ""]


def test_unknown_method_names_the_known_ones(tmp_path):
    with pytest.raises(PlanError, match=r"unknown method 'nope'.*trivial.*olatbench methods list"):
        make_plan("nope", support.tiny_suite(), tmp_path, data_root=tmp_path)


def test_set_overrides_reach_the_config_label_folder_and_id(tmp_path):
    from olatbench.bench.plan import parse_overrides

    data = support.write_tiny_data(tmp_path / "data")
    overrides = parse_overrides(["lr=0.5", "noise=1e-3", "fail_at_step=-1"])
    assert overrides == {"lr": 0.5, "noise": 0.001, "fail_at_step": -1}
    base = make_plan(
        "trivial", support.tiny_suite(), tmp_path / "runs", data_root=data, progress=False
    )[0]
    job = make_plan(
        "trivial",
        support.tiny_suite(),
        tmp_path / "runs",
        data_root=data,
        progress=False,
        variants=["ablation-B"],
        iterations=5,
        overrides=overrides,
    )[0]
    assert job.config["lr"] == 0.5 and job.config["noise"] == 0.001  # after the variant preset
    assert job.config["iterations"] == 5  # --iterations still wins
    assert job.variant == "ablation-B~fail_at_step=-1,iterations=5,lr=0.5,noise=0.001"
    assert job.folder == str(
        job_folder(tmp_path / "runs", "tiny", "trivial", job.variant, job.scene, 0)
    )
    assert job.id != base.id
    assert parse_overrides(["shadow_mode=density", "background=[1, 1, 1]", "flag=true"]) == {
        "shadow_mode": "density",
        "background": [1, 1, 1],
        "flag": True,
    }


def test_iterations_option_is_exactly_the_iterations_override(tmp_path):
    data = support.write_tiny_data(tmp_path / "data")

    def job(**kwargs):
        return make_plan(
            "trivial",
            support.tiny_suite(),
            tmp_path / "runs",
            data_root=data,
            progress=False,
            scenes=["Alpha"],
            **kwargs,
        )[0]

    spelled = job(iterations=5)
    assert spelled == job(overrides={"iterations": 5})  # same label, folder, config and id
    assert spelled.variant == "default~iterations=5" and spelled.iterations == 5
    full = job()
    # a full run never meets a short one
    assert full.folder != spelled.folder and full.variant == "default"
    assert job(iterations=8).folder != spelled.folder
    assert job(iterations=5, overrides={"iterations": 5}) == spelled
    with pytest.raises(PlanError, match="disagree"):
        job(iterations=5, overrides={"iterations": 8})


def test_a_method_spec_fixes_its_own_iteration_count(tmp_path):
    from olatbench.methods.registry import register
    from olatbench.methods.spec import MethodSpec

    data = support.write_tiny_data(tmp_path / "data")
    trivial = get_spec("trivial")
    for name, iterations in (("fixed-seven", 7), ("learning-free", 0)):
        register(
            MethodSpec(
                name=name,
                description="test",
                implementation=trivial.implementation,
                config=trivial.config,
                iterations=iterations,
            )
        )
    suite = support.tiny_suite(name="other", iterations=3000)
    planned = make_plan("fixed-seven", suite, tmp_path / "runs", data_root=data, progress=False)[0]
    assert planned.iterations == 7  # the method's own count, not the suite's 3000
    assert (
        make_plan(
            "fixed-seven", suite, tmp_path / "runs", data_root=data, progress=False, iterations=9
        )[0].iterations
        == 9
    )  # an explicit override still wins
    assert (
        make_plan("learning-free", suite, tmp_path / "runs", data_root=data, progress=False)[
            0
        ].iterations
        == 0
    )
    with pytest.raises(PlanError, match="learns nothing"):
        make_plan(
            "learning-free", suite, tmp_path / "runs", data_root=data, progress=False, iterations=5
        )
    with pytest.raises(ValueError, match="iterations must be"):
        MethodSpec(
            name="x",
            description="",
            implementation=trivial.implementation,
            config=trivial.config,
            iterations=-1,
        )


def test_bad_overrides_are_one_clear_error(tmp_path):
    from olatbench.bench.plan import parse_overrides

    with pytest.raises(PlanError, match="KEY=VALUE"):
        parse_overrides(["lr"])
    data = support.write_tiny_data(tmp_path / "data")
    with pytest.raises(PlanError, match=r"no config field nope; its fields: .*lr"):
        make_plan(
            "trivial",
            support.tiny_suite(),
            tmp_path,
            data_root=data,
            progress=False,
            overrides={"nope": 1},
        )
    pytest.importorskip("olatbench.methods.ssdgs")
    with pytest.raises(PlanError, match="refine_camera"):  # the method's own validation, named
        make_plan(
            "ssdgs",
            "mini",
            tmp_path,
            data_root=data,
            progress=False,
            generate=False,
            overrides={"test_time_refinement": True},
        )
