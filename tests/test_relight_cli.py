"""``olatbench render --lights/--envmap`` and ``olatbench export --under-light`` a lighting (#57),
end to end on a tiny trained SSD-GS job."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from test_export import columns, parse_ply
from trained_jobs import train_tiny

from olatbench.bench.relight import restore_relighter
from olatbench.cli import main
from olatbench.datasets import colour, load_scene
from olatbench.datasets.images import read_image

SH_C0 = 0.28209479177387814


@pytest.fixture(scope="module")
def ssdgs_job(tmp_path_factory):
    return train_tiny(
        "ssdgs",
        tmp_path_factory.mktemp("relight_ssdgs"),
        iterations=8,
        shadow_resolution=32,
        init_opacity=0.6,
    )


def lights_file(path, *lights) -> str:
    path.write_text(
        json.dumps(
            {"lights": [{"type": "point", "position": list(p), "intensity": i} for p, i in lights]}
        )
    )
    return str(path)


def test_render_lights_still_is_the_sum_of_single_light_stills(ssdgs_job, tmp_path):
    relighter, _ = restore_relighter(ssdgs_job)
    ref = relighter.reference
    a, b = (
        ref.centre + ref.distance * np.array([0.6, 0.0, 0.8]),
        ref.centre + ref.distance * np.array([0, 0.6, 0.8]),
    )
    stills = {}
    for name, lights in (("a", [(a, 2.0)]), ("b", [(b, 3.0)]), ("both", [(a, 2.0), (b, 3.0)])):
        result = CliRunner().invoke(
            main,
            [
                "render",
                str(ssdgs_job),
                "--lights",
                lights_file(tmp_path / f"{name}.json", *lights),
                "-o",
                str(tmp_path / "out"),
                "--quiet",
            ],
        )
        assert result.exit_code == 0, result.output
        assert f"{name}.png" in result.output and f"{name}.exr" in result.output
        stills[name] = read_image(tmp_path / "out" / f"{name}.exr")
    assert stills["a"].max() > 1e-3 and stills["b"].max() > 1e-3
    np.testing.assert_allclose(stills["both"], stills["a"] + stills["b"], rtol=1e-5, atol=1e-6)
    shown = read_image(tmp_path / "out" / "both.png")
    expected = np.clip(colour.convert_colourspace(stills["both"], "linear", "srgb"), 0.0, 1.0)
    assert np.abs(shown - expected).max() <= 0.5 / 255 + 1e-6


def test_render_envmap_orbit_writes_a_video(ssdgs_job, tmp_path):
    result = CliRunner().invoke(
        main,
        [
            "render",
            str(ssdgs_job),
            "--envmap",
            "studio",
            "--samples",
            "3",
            "--orbit",
            "--frames",
            "2",
            "-o",
            str(tmp_path / "v"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "v" / "orbit-studio.mp4").is_file()
    frames = sorted((tmp_path / "v" / "orbit-studio_frames").glob("*.png"))
    assert len(frames) == 2 and "3 lights per frame" in result.output
    assert not np.array_equal(read_image(frames[0]), read_image(frames[1]))  # the camera moved


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--sweep", "light-orbit"], "go without --lights"),
        (["--light", "0"], "go without --lights"),
        (["--component", "shadow"], "only rgb adds up"),
        (["--envmap", "sky"], "--lights or --envmap, not both"),
        (["--frames", "3"], "--frames goes with --camera-path or --orbit"),
        (["--orbit", "--start-frame", "r_0000"], "--start-frame goes without"),
    ],
)
def test_render_lighting_option_conflicts_are_usage_errors(ssdgs_job, tmp_path, extra, message):
    path = lights_file(tmp_path / "one.json", ([0, 0, 5], 1.0))
    result = CliRunner().invoke(main, ["render", str(ssdgs_job), "--lights", path, *extra])
    assert result.exit_code == 2 and message in result.output


def test_render_a_bad_lighting_file_names_the_file_and_field(ssdgs_job, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"lights": [{"type": "point", "position": [0, 0], "intensity": 1}]}))
    result = CliRunner().invoke(main, ["render", str(ssdgs_job), "--lights", str(bad)])
    assert (
        result.exit_code == 2
        and "bad.json" in result.output
        and "lights[0].position" in result.output
    )
    assert "Traceback" not in result.output
    missing = CliRunner().invoke(
        main, ["render", str(ssdgs_job), "--envmap", str(tmp_path / "nowhere.exr")]
    )
    assert missing.exit_code == 2 and "nowhere.exr" in missing.output


def test_export_under_a_lighting_sums_in_linear_light(ssdgs_job, tmp_path):
    """Doubling every light of a lighting doubles each Gaussian's baked colour in linear light (the
    colours one test camera sees: degree 0 of one view is the colour itself)."""
    relighter, job = restore_relighter(ssdgs_job)
    view = load_scene(job.scene_path, format=job.scene_format).split(job.test_split)[0].frame_id
    ref = relighter.reference
    a, b = (
        ref.centre + ref.distance * np.array([0.6, 0.0, 0.8]),
        ref.centre + ref.distance * np.array([0, 0.6, 0.8]),
    )
    linear = {}
    for scale in (1.0, 2.0):
        path = lights_file(tmp_path / f"x{scale}.json", (a, 1.0 * scale), (b, 0.5 * scale))
        out = tmp_path / f"x{scale}.ply"
        result = CliRunner().invoke(
            main,
            [
                "export",
                str(ssdgs_job),
                "--under-light",
                path,
                "--view",
                view,
                "-o",
                str(out),
                "--quiet",
            ],
        )
        assert result.exit_code == 0, result.output
        comments, _, table = parse_ply(out)
        assert any("(2 lights, summed in linear light)" in line for line in comments)
        srgb = 0.5 + SH_C0 * columns(table, "f_dc_", 3).astype(np.float64)
        linear[scale] = colour.convert_colourspace(srgb, "srgb", "linear")
    assert linear[1.0].max() > 1e-3
    np.testing.assert_allclose(linear[2.0], 2.0 * linear[1.0], rtol=1e-3, atol=1e-5)
    envmap = CliRunner().invoke(
        main,
        [
            "export",
            str(ssdgs_job),
            "--under-light",
            "furnace",
            "--samples",
            "2",
            "--view",
            view,
            "-o",
            str(tmp_path / "f.ply"),
            "--quiet",
        ],
    )
    assert envmap.exit_code == 0, envmap.output
    stray = CliRunner().invoke(
        main,
        [
            "export",
            str(ssdgs_job),
            "--under-light",
            "0",
            "--samples",
            "2",
            "-o",
            str(tmp_path / "g.ply"),
        ],
    )
    assert stray.exit_code == 2 and "--samples goes with" in stray.output
