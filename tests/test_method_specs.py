"""Method specs and the torch-free registry: `methods list/show` and `run --dry-run` import no
torch, the runner expands `--ablation` from the spec, built-in specs agree with their classes,
plugins (spec or class) and stale entry points named like built-ins."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from waiting import BACKSTOP_SECONDS

from olatbench.bench.jobs import code_hash
from olatbench.devices import resolve_device
from olatbench.methods import registry
from olatbench.methods.spec import MethodSpec

ROOT = Path(__file__).resolve().parents[1]
BUILTIN = ("ssdgs", "3dgs", "gs3")


def _cli_without_torch(args: list[str], env_path: list[str] = ()) -> dict:
    """Run the click main in a fresh interpreter; report its output, exit code and whether torch was
    imported."""
    script = textwrap.dedent(f"""
        import io, json, sys, contextlib
        from olatbench.cli import main
        out = io.StringIO()
        code = 0
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            try:
                main({args!r})
            except SystemExit as exit:
                code = exit.code or 0
        print(json.dumps({{"output": out.getvalue(), "code": code, "torch": "torch" in sys.modules}}))
    """)  # noqa: E501
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *env_path])}
    result = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
        env=env,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.splitlines()[-1])


def test_methods_list_and_show_import_no_torch():
    listed = _cli_without_torch(["methods", "list"])
    assert listed["code"] == 0, listed["output"]
    for name in BUILTIN:
        assert f"{name}" in listed["output"]
    assert "[native]" in listed["output"] and "ablation-A" in listed["output"]
    shown = _cli_without_torch(["methods", "show", "ssdgs"])
    assert shown["code"] == 0, shown["output"]
    assert "components: ablation-A, ablation-B" in shown["output"] and "num_asg" in shown["output"]
    assert "outputs: rgb, diffuse, specular, sss, shadow, shadow_coarse, alpha" in shown["output"]
    assert not listed["torch"] and not shown["torch"]
    diff = _cli_without_torch(["methods", "diff", "ssdgs", "--variant", "mini"])
    official = _cli_without_torch(
        ["methods", "show", "ssdgs", "--suite", "mini", "--variant", "official"]
    )
    assert diff["code"] == 0 and official["code"] == 0, diff["output"] + official["output"]
    assert "num_asg: 4 (variant mini); authors' 8 at arguments/__init__.py:69" in diff["output"]
    assert not diff["torch"] and not official["torch"]


def test_ablation_dry_run_imports_no_torch_and_expands_the_specs_grid(tmp_path):
    result = _cli_without_torch(
        [
            "run",
            "--method",
            "ssdgs",
            "--suite",
            "mini",
            "--ablation",
            "components",
            "--scenes",
            "diffuse_shadow",
            "--dry-run",
            "-o",
            str(tmp_path / "runs"),
        ]
    )
    assert result["code"] == 0, result["output"]
    assert not result["torch"]
    for letter in "ABCDEF":
        assert f"ablation-{letter}" in result["output"]


def test_a_dry_run_with_a_stored_calibration_names_auto_without_torch(tmp_path, monkeypatch):
    """#48: a calibration stored by an earlier ``--dry-run --calibrate`` made every later dry run
    import torch to name ``--device auto``; the calibration now stores what auto named, and the dry
    run reads it."""
    from click.testing import CliRunner

    import olatbench.bench.estimate as estimate
    from olatbench.cli import main

    timed = []
    monkeypatch.setattr(
        estimate,
        "calibrate",
        lambda job, progress=True: (
            timed.append(job.device)
            or
            # not timing: the file is the point
            estimate.StepCost(a=0.5, b=0.0, measured={"0": 0.5})
        ),
    )
    args = [
        "run",
        "--method",
        "ssdgs",
        "--suite",
        "mini",
        "--scenes",
        "diffuse_shadow",
        "--iterations",
        "20",
        "--dry-run",
        "-o",
        str(tmp_path / "runs"),
    ]
    calibrated = CliRunner().invoke(main, [*args, "--calibrate", "--quiet"])
    assert calibrated.exit_code == 0, calibrated.output
    assert timed == [resolve_device("auto")]
    result = _cli_without_torch(args)
    assert result["code"] == 0, result["output"]
    assert not result["torch"]
    # 20 steps at 0.5 s: the stored calibration was used
    assert "10 s" in result["output"], result["output"]


def test_official_method_list_show_and_dry_run_import_no_torch(tmp_path):
    shown = _cli_without_torch(["methods", "show", "gs3-official"])
    result = _cli_without_torch(
        [
            "run",
            "--method",
            "gs3-official",
            "--suite",
            "mini",
            "--dry-run",
            "-o",
            str(tmp_path / "runs"),
        ]
    )
    assert shown["code"] == 0 and result["code"] == 0, result["output"]
    assert "gs3-official" in result["output"] and "3 job(s)" in result["output"]
    assert not shown["torch"] and not result["torch"]


def test_unknown_ablation_grid_lists_the_methods_grids(tmp_path):
    result = _cli_without_torch(
        [
            "run",
            "--method",
            "gs3",
            "--suite",
            "mini",
            "--ablation",
            "components",
            "--dry-run",
            "-o",
            str(tmp_path / "runs"),
        ]
    )
    assert result["code"] == 2  # a usage error
    assert "method 'gs3' has no ablation grid 'components'; its grids: none" in result["output"]
    result = _cli_without_torch(
        [
            "run",
            "--method",
            "ssdgs",
            "--suite",
            "mini",
            "--ablation",
            "lighting",
            "--dry-run",
            "-o",
            str(tmp_path / "runs"),
        ]
    )
    assert "its grids: components, schedule, shadow-on-sss" in result["output"]


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_spec_agrees_with_its_class(name):
    spec = registry.get_spec(name)
    method_class = registry.get_method(name)
    assert spec.implementation == f"{method_class.__module__}:{method_class.__qualname__}"
    assert spec.load_config_class() is method_class.config_class
    assert {k: dict(v) for k, v in spec.presets.items()} == method_class.presets
    assert spec.description == method_class.description
    # located without import == inspected
    assert code_hash(spec.implementation) == code_hash(method_class)
    for preset in spec.presets:
        assert _outcome(spec.resolve_config, preset) == _outcome(
            method_class.resolve_config, preset
        )


def _outcome(resolve, preset: str):
    """The config, or the error message of a preset that is invalid on its own
    (test-time-refinement)."""
    try:
        return resolve(preset)
    except ValueError as error:
        return str(error)


def test_composed_presets_resolve_the_same_everywhere():
    from olatbench.methods.ssdgs import SSDGS
    from olatbench.methods.ssdgs.presets import PRESETS

    spec = registry.get_spec("ssdgs")
    config = SSDGS.resolve_config("mini+ablation-C", iterations=7)
    assert config == spec.resolve_config("mini+ablation-C", iterations=7)
    assert (config.iterations, config.use_shadow, config.num_init_gaussians) == (7, False, 2_000)
    assert dataclasses.asdict(config) == dataclasses.asdict(
        spec.load_config_class()(**{**PRESETS["mini"], **PRESETS["ablation-C"], "iterations": 7})
    )
    with pytest.raises(
        KeyError, match=r"method 'ssdgs' has no preset 'ablation-Z'; known presets: .*mini"
    ):
        SSDGS.resolve_config("mini+ablation-Z")


def test_spec_rejects_a_grid_naming_unknown_presets():
    with pytest.raises(ValueError, match=r"ablation grid 'g' names unknown presets \['b'\]"):
        MethodSpec(
            name="m",
            description="",
            implementation="a:B",
            config="a:C",
            presets={"a": {}},
            ablations={"g": ("default", "a", "a+b")},
        )


def _plugin_site(tmp_path: Path, entries: str, module: str) -> list[str]:
    site = tmp_path / "site"
    dist = site / "olatbench_test_plugin-0.1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: olatbench-test-plugin\nVersion: 0.1.0\n"
    )
    (dist / "entry_points.txt").write_text("[olatbench.methods]\n" + entries)
    (site / "olatbench_test_plugin.py").write_text(module)
    return [str(site)]


def test_plugin_spec_entry_point_and_stale_builtin_entry_points(tmp_path):
    path = _plugin_site(
        tmp_path,
        textwrap.dedent("""\
        toy = olatbench_test_plugin:SPEC
        ssdgs = olatbench_test_plugin:DOES_NOT_EXIST
        gs3 = olatbench.methods.baselines.gs3:GS3
    """),
        textwrap.dedent("""\
        from olatbench.methods.spec import MethodSpec
        SPEC = MethodSpec(name="toy", description="A plugin described by a spec.",
                          implementation="olatbench_test_plugin:Toy", config="olatbench_test_plugin:ToyConfig",
                          kind="plugin", presets={"fast": {"iterations": 3}}, ablations={"speed": ("default", "fast")})
    """),  # noqa: E501
    )
    listed = _cli_without_torch(["methods", "list"], path)
    assert listed["code"] == 0, listed["output"]
    # names padded
    assert re.search(r"^toy +\[plugin\] A plugin described by a spec\.$", listed["output"], re.M)
    # the stale 'ssdgs' entry point is ignored: the built-in wins
    assert "unavailable" not in listed["output"]
    # (ssdgs-official is another method)
    assert len(re.findall(r"^ssdgs ", listed["output"], re.M)) == 1
    assert not listed["torch"]  # the old 'gs3' class entry is not imported
    shown = _cli_without_torch(["methods", "show", "toy"], path)
    assert "speed: default, fast" in shown["output"]
    # its config module has no ToyConfig: said, not a crash
    assert "cannot be imported" in shown["output"]


def test_register_spec_and_class_in_process():
    spec = MethodSpec(
        name="in-process",
        description="d",
        implementation="test_runner_support:TrivialMethod",
        config="test_runner_support:TrivialConfig",
        kind="plugin",
        presets={"tiny": {"iterations": 1}},
    )
    registry.register(spec)
    try:
        assert registry.get_spec("in-process") is spec
        assert "in-process" in registry.method_names()
        import test_runner_support

        assert registry.get_method("in-process") is test_runner_support.TrivialMethod
    finally:
        registry._registered.pop("in-process")
    with pytest.raises(KeyError, match=r"unknown method 'in-process'; known methods: .*ssdgs"):
        registry.get_spec("in-process")
