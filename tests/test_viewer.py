"""`olatbench view`: the viser server on a tiny trained SSD-GS job, driven by a websocket client
like a browser."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import cv2
import numpy as np
import pytest
import test_runner_support as support
from click.testing import CliRunner
from trained_jobs import train_tiny_ssdgs
from waiting import BACKSTOP_SECONDS, wait_until

from olatbench.cli import main
from olatbench.datasets import colour
from olatbench.reports.jobfolder import JobFolder, read_png

pytest.importorskip("viser")
pytest.importorskip("olatbench.gaussians.shadow")
from viser import _messages
from viser_client import ViserTestClient, decode_image

from olatbench.viewer.geometry import MAX_RESOLUTION, browser_camera, camera_pose
from olatbench.viewer.model import ViewerModel
from olatbench.viewer.server import ViewerApp, ViewRequest


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    # After 16 steps the learned shading frame (mini's) is still the identity: every normal is +z,
    # so a light moved in azimuth would leave n·ωi unchanged. The smallest-scale frame gives the
    # tiny model varied normals.
    return train_tiny_ssdgs(
        tmp_path_factory.mktemp("viewer"), shading_frame="min_scale", orient_normals=True
    )


@pytest.fixture(scope="module")
def app(trained):
    model = ViewerModel.open(trained)
    with ViewerApp([trained], model, port=0, settle_seconds=0.05) as running:
        yield running


def full_image(client: ViserTestClient, model: ViewerModel, after: int = 0) -> np.ndarray:
    """The next background image at the scene's resolution (previews are smaller)."""
    height = model.full_size[1]
    message = client.wait_for(
        lambda m: (
            m.get("type") == "BackgroundImageMessage"
            and m.get("rgb_data") is not None
            and cv2.imdecode(np.frombuffer(m["rgb_data"], np.uint8), 1).shape[0] == height
        ),
        after=after,
    )
    return cv2.imdecode(np.frombuffer(message["rgb_data"], np.uint8), 1)[..., ::-1].astype(
        np.float64
    )


def connect_home(app: ViewerApp) -> ViserTestClient:
    """A tab whose browser camera sits at the home (first test) frame, canvas of the scene's
    aspect."""
    model = app.model(app.folders[0])
    client = ViserTestClient(app.port)
    wxyz, position, fov = camera_pose(model.home.camera)
    client.send_camera(wxyz, position, fov, *model.full_size)
    return client


def test_server_serves_the_page_on_a_free_port(app):
    with urllib.request.urlopen(app.url, timeout=BACKSTOP_SECONDS) as response:
        page = response.read().decode("utf-8", "replace")
    assert response.status == 200 and "<html" in page.lower() and "<script" in page.lower()


def test_moving_the_light_changes_the_image_in_the_shadowed_region(app):
    model = app.model(app.folders[0])
    client = connect_home(app)
    try:
        first = full_image(client, model)
        owner = client.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
        session = app.sessions[int(owner)]
        request = session.delivered.request
        camera = browser_camera(
            np.asarray(request.wxyz),
            np.asarray(request.position),
            request.fov,
            first.shape[1],
            first.shape[0],
        )
        shadow = model.render_outputs(camera, request.light)["shadow"][..., 0].numpy()
        azimuth, elevation, distance = model.light_frame.spherical(request.light.position)
        moved = model.light_frame.position(azimuth + 120.0, elevation, distance)
        mark = len(client.received)
        client.send(
            _messages.TransformControlsUpdateMessage(
                name="/light", wxyz=(1.0, 0.0, 0.0, 0.0), position=tuple(moved), owner=owner
            )
        )
        second = full_image(client, model, after=mark)
    finally:
        client.close()
    np.testing.assert_allclose(session.delivered.request.light.position, moved)
    assert session.azimuth.value == pytest.approx(
        ((azimuth + 120.0 + 180.0) % 360.0) - 180.0, abs=0.1
    )
    shadowed = shadow < np.median(shadow)  # the darker-shadowed half of the first view
    assert shadowed.sum() > 0
    difference = np.abs(second - first).mean(axis=2)
    # 8-bit levels, far above JPEG noise (same image twice: 0)
    assert difference[shadowed].mean() > 3.0


def test_a_tab_whose_first_camera_message_beats_its_set_up_still_gets_an_image(app, monkeypatch):
    """viser sets a tab up in a thread pool beside its connection: the browser's first camera
    message can arrive before the session's camera handler exists. The session must answer it anyway
    (found with headless Chromium, where the tab then stayed black or showed the frame's shape
    stretched)."""
    from olatbench.viewer import server

    use_model = server.ClientSession.use_model

    def late_set_up(session, model):
        # hold the set-up until the first camera message has come and gone unanswered
        wait_until(
            lambda: server._camera_state_received(session.client.camera),
            "first camera message",
            poll=0.01,
        )
        use_model(session, model)

    monkeypatch.setattr(server.ClientSession, "use_model", late_set_up)
    model = app.model(app.folders[0])
    width, height = model.full_size
    client = ViserTestClient(app.port)
    wxyz, position, fov = camera_pose(model.home.camera)
    # a canvas twice as wide as the frame
    client.send_camera(wxyz, position, fov, 2 * width, height)
    try:
        image = full_image(client, model)
    finally:
        client.close()
    # the canvas's aspect, not the frame's (what the tab showed when the first message went
    # unanswered)
    assert image.shape[1] / image.shape[0] == pytest.approx(2 * width / height, rel=0.03)


def test_snapping_to_a_test_frame_reproduces_the_stored_test_render(app, trained):
    client = connect_home(app)
    try:
        owner = client.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
        session = app.sessions[int(owner)]
        model = session.model
        frame = model.test[-1]
        session.snap(frame)
        assert app.scheduler.wait_idle(60)
    finally:
        client.close()
    comparison = session.comparison
    assert comparison is not None and comparison.frame is frame
    stored = np.round(
        read_png(JobFolder.open(trained).render_path("test", frame.frame_id)) * 255
    ).astype(np.uint8)
    np.testing.assert_array_equal(comparison.render, stored)
    truth = frame.frame.load(colourspace=model.job.colourspace, background="official").rgb
    render = colour.convert_colourspace(
        stored.astype(np.float64) / 255, "srgb", model.job.colourspace
    )
    mse = np.mean((np.clip(render, 0, 1) - np.clip(truth, 0, 1)) ** 2)
    # the stored render is 8-bit
    assert comparison.psnr == pytest.approx(-10 * np.log10(mse), abs=0.3)
    recorded = json.loads((trained / "results.json").read_text())["metrics"]["test"]["per_image"][
        frame.frame_id
    ]
    assert comparison.recorded_psnr == recorded["psnr"]
    np.testing.assert_allclose(session.light_handle.position, frame.light.position)


def test_snap_to_a_frame_name_not_in_the_list_is_said_in_the_tab_not_raised_on_the_server(app):
    """The tab sends the dropdown's value as text: a name that is no frame
    (a stale or forged message) must give one line in the tab and leave the camera and light where
    they were; the click handler raises nothing into viser's thread, which would print a traceback
    on the server and tell the browser nothing (#48)."""
    client = connect_home(app)
    try:
        dropdown = client.wait_for(
            lambda m: m.get("type") == "GuiDropdownMessage" and m["props"]["label"] == "frame"
        )
        owner = client.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
        session = app.sessions[int(owner)]
        # the tab's first image, whose status line would overwrite the one checked
        full_image(client, session.model)
        light = np.array(session.light_handle.position)
        client.send(_messages.GuiUpdateMessage(dropdown["uuid"], {"value": "test/no-such-frame"}))
        wait_until(
            lambda: str(session.frame_dropdown.value) == "test/no-such-frame",
            "the forged frame name",
        )
        session._snap_clicked(None)  # what viser runs when the tab's Snap button is clicked
    finally:
        client.close()
    assert (
        session.status.content
        == f"**cannot snap**: {session.model.label}: no frame 'test/no-such-frame'"
    )
    np.testing.assert_array_equal(session.light_handle.position, light)


def test_two_tabs_have_their_own_light(app):
    model = app.model(app.folders[0])
    first, second = connect_home(app), connect_home(app)
    try:
        owners = [
            c.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
            for c in (first, second)
        ]
        assert owners[0] != owners[1]
        sessions = [app.sessions[int(owner)] for owner in owners]
        full_image(first, model)
        full_image(second, model)
        moved = model.light_frame.position(10.0, 40.0, 2.0)
        mark = len(first.received)
        first.send(
            _messages.TransformControlsUpdateMessage(
                name="/light", wxyz=(1.0, 0.0, 0.0, 0.0), position=tuple(moved), owner=owners[0]
            )
        )
        full_image(first, model, after=mark)
        np.testing.assert_allclose(sessions[0].light_handle.position, moved)
        np.testing.assert_allclose(sessions[1].light_handle.position, model.home.light.position)
        np.testing.assert_allclose(
            sessions[1].delivered.request.light.position, model.home.light.position
        )
    finally:
        first.close()
        second.close()


def test_a_run_folder_serves_each_finished_job_and_a_tab_switches_between_them(trained, tmp_path):
    run = tmp_path / "run"
    for seed in (0, 1):  # two finished jobs below one run folder, one unfinished
        shutil.copytree(trained, run / f"seed{seed}")
    shutil.copytree(trained, run / "seed2", ignore=shutil.ignore_patterns("step_*.pt"))
    from olatbench.viewer.jobs import job_folders

    folders, skipped = job_folders(run)
    assert (
        folders == [run / "seed0", run / "seed1"]
        and len(skipped) == 1
        and "no checkpoint" in skipped[0]
    )
    with ViewerApp(folders, ViewerModel.open(folders[0]), port=0, settle_seconds=0.05) as viewer:
        client = connect_home(viewer)
        try:
            dropdown = client.wait_for(
                lambda m: m.get("type") == "GuiDropdownMessage" and m["props"]["label"] == "job"
            )
            owner = client.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
            session = viewer.sessions[int(owner)]
            assert session.model.folder == folders[0]
            mark = len(client.received)
            client.send(_messages.GuiUpdateMessage(dropdown["uuid"], {"value": str(folders[1])}))
            # the second job is restored on first use, on viser's thread pool
            wait_until(lambda: session.model.folder == folders[1], "switch to the second job")
            # The model is assigned first and its render submitted at the end of the set-up, so
            # "idle" alone can still show the old job's image (the two jobs are copies, so their
            # images cannot tell them apart).
            wait_until(
                lambda: (
                    viewer.scheduler.idle()
                    and session.delivered is not None
                    and session.delivered.request.model is session.model
                ),
                "render of the second job",
                poll=0.01,
            )
            full_image(client, session.model, after=mark)
        finally:
            client.close()


def test_renders_fill_the_browser_window_capped_by_max_resolution(app):
    """The full-resolution render has the canvas's size (not the scene's 48-pixel height stretched),
    its longer side capped at max_resolution."""
    model = app.model(app.folders[0])
    wxyz, position, fov = camera_pose(model.home.camera)
    for cap, canvas, expected in ((512, (300, 200), (200, 300)), (120, (300, 200), (80, 120))):
        app.max_resolution = cap
        client = ViserTestClient(app.port)
        try:
            client.send_camera(wxyz, position, fov, *canvas)
            client.wait_for(
                lambda m, shape=expected: (
                    m.get("type") == "BackgroundImageMessage"
                    and m.get("rgb_data") is not None
                    and decode_image(m["rgb_data"]).shape[:2] == shape
                )
            )
        finally:
            client.close()
            app.max_resolution = MAX_RESOLUTION


def gui_message(client: ViserTestClient, label: str) -> dict:
    """The message that added the tab's GUI control named ``label``."""
    return client.wait_for(
        lambda m: (
            str(m.get("type", "")).startswith("Gui") and m.get("props", {}).get("label") == label
        )
    )


def test_the_environment_map_mode_refines_to_the_render_image_and_restarts_on_a_camera_move(
    app, trained, monkeypatch
):
    from olatbench.bench.relight import restore_relighter, shown
    from olatbench.datasets.lighting import environment_lighting
    from olatbench.reports.video import sample_lighting
    from olatbench.viewer.environment import ENVIRONMENT_MODE, POINT_MODE

    model = app.model(app.folders[0])
    samples = 24
    # a pass per 2 samples: 1 + 10 passes of a still view
    monkeypatch.setattr(app, "batch_samples", 2)
    refine = model.refine

    def slow_refine(*args, **kwargs):  # time for the camera to move while the view refines
        time.sleep(0.05)
        return refine(*args, **kwargs)

    monkeypatch.setattr(model, "refine", slow_refine)
    client = connect_home(app)
    try:
        owner = client.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
        session = app.sessions[int(owner)]
        full_image(client, model)
        shown_images = []
        show = session.show

        def recording_show(request, result, quality, seconds, step, samples=None):
            shown_images.append((request, quality, samples))
            show(request, result, quality, seconds, step, samples)

        monkeypatch.setattr(session, "show", recording_show)
        client.send(
            _messages.GuiUpdateMessage(gui_message(client, "samples")["uuid"], {"value": samples})
        )
        client.send(
            _messages.GuiUpdateMessage(gui_message(client, "rotation °")["uuid"], {"value": 40.0})
        )
        client.send(
            _messages.GuiUpdateMessage(
                gui_message(client, "lighting")["uuid"], {"value": ENVIRONMENT_MODE}
            )
        )
        wait_until(
            lambda: len([s for _, q, s in shown_images if q == "full" and s]) >= 3,
            "three refinement passes",
            poll=0.005,
        )
        first_request = shown_images[-1][0]
        wxyz, position, fov = camera_pose(model.home.camera)
        moved = np.asarray(position) * 1.1  # the camera backs off during the refinement
        client.send_camera(wxyz, moved, fov, *model.full_size)
        wait_until(
            lambda: (
                app.scheduler.idle()
                and session.delivered.request.position == tuple(moved)
                and session.delivered.samples == (samples, samples)
            ),
            "the moved view refined",
            poll=0.01,
        )
        converged = session.delivered
        assert not session.light_folder.visible and not session.light_handle.visible
        client.send(
            _messages.GuiUpdateMessage(
                gui_message(client, "lighting")["uuid"], {"value": POINT_MODE}
            )
        )
        wait_until(
            lambda: app.scheduler.idle() and session.delivered is not converged,
            "back to the point light",
            poll=0.01,
        )
        assert (
            isinstance(session.delivered.request, ViewRequest) and session.delivered.samples is None
        )
        assert (
            session.light_folder.visible
            and session.light_handle.visible
            and not session.env_folder.visible
        )
    finally:
        client.close()
    first = [s[0] for r, q, s in shown_images if r is first_request]
    # refined two samples a pass, then cancelled
    assert first[:3] == [4, 6, 8] and first[-1] < samples
    second_request = converged.request
    second = [(q, s[0]) for r, q, s in shown_images if r is second_request]
    # from the start: 4, then 2 a pass
    assert second[-11:] == [("full", n) for n in range(4, samples + 1, 2)]
    # the moving view's previews (4 samples)
    assert all(q == "preview" and n == 4 for q, n in second[:-11])
    assert not [
        r
        for r, _, _ in shown_images[
            shown_images.index(
                next(
                    x
                    for x in shown_images
                    if x[0]
                    is
                    # nothing of the old view after the new one's first
                    second_request
                )
            ) :
        ]
        if r is first_request
    ]
    # the converged image is what 'olatbench render --envmap studio --samples 24' renders
    # (same samples)
    relighter, _ = restore_relighter(trained)
    job = JobFolder.open(trained)
    lights = sample_lighting(job, environment_lighting("studio", samples, rotation=40.0))
    image = converged.image
    camera = browser_camera(
        np.asarray(second_request.wxyz),
        np.asarray(second_request.position),
        second_request.fov,
        image.shape[1],
        image.shape[0],
    )
    expected = colour.quantize_8bit(shown(relighter.linear(camera, lights))).astype(int)
    # float32 sums in another order: a rounding at most
    assert np.abs(image.astype(int) - expected).max() <= 1
    assert np.abs(image.astype(int) - expected).mean() < 0.01


def write_earlier_checkpoint(job: Path, final: Path, step: int) -> None:
    """A checkpoint of ``job`` at ``step`` as the runner would have written it mid-training (the
    runner keeps only the final one of a finished job): the final state with that step and a darker
    diffuse albedo."""
    import torch

    from olatbench.bench.checkpoints import load_checkpoint
    from olatbench.bench.restore import read_job

    payload = load_checkpoint(final, read_job(job).id)
    payload["step"] = payload["method"]["step"] = step
    payload["method"]["model"]["attributes.diffuse"] -= 2.0
    torch.save(payload, final.with_name(f"step_{step:08d}.pt"))


def test_a_job_still_training_is_followed_to_its_newest_checkpoint(trained, tmp_path):
    job = tmp_path / "job"
    shutil.copytree(trained, job)
    final = job / "checkpoints" / "step_00000016.pt"
    write_earlier_checkpoint(job, final, 8)
    held = tmp_path / "held.pt"
    final.rename(held)  # the runner has not written its last checkpoint yet
    from olatbench.viewer.jobs import job_folders

    assert job_folders(job) == ([job], [])
    model = ViewerModel.open(job)
    assert model.step == 8 and not model.finished and "step 8/16, training" in model.label
    with ViewerApp([job], model, port=0, settle_seconds=0.05, follow_seconds=0.05) as viewer:
        client = connect_home(viewer)
        try:
            owner = client.wait_for(lambda m: m.get("type") == "TransformControlsMessage")["owner"]
            session = viewer.sessions[int(owner)]
            earlier = full_image(client, model)
            assert session.delivered.step == 8
            mark = len(client.received)
            held.replace(final)  # the runner writes it (atomically, by a rename)
            client.wait_for(
                lambda m: (
                    m.get("type") == "BackgroundImageMessage" and session.delivered.step == 16
                ),
                after=mark,
            )
        finally:
            client.close()
    assert model.step == 16 and model.finished and "training" not in model.label
    request = session.delivered.request
    camera = browser_camera(
        np.asarray(request.wxyz),
        np.asarray(request.position),
        request.fov,
        *session.delivered.image.shape[1::-1],
    )
    finished = ViewerModel.open(trained)
    np.testing.assert_array_equal(
        session.delivered.image, finished.render(camera, request.light, request.component)
    )
    assert session.delivered.image.mean() > 1.2 * earlier.mean()  # the albedo of step 8 was darker


def test_bad_folders_fail_before_a_server_starts(trained, tmp_path):
    runner = CliRunner()
    empty = runner.invoke(main, ["view", str(tmp_path)])
    assert empty.exit_code == 2 and "no job.json in or below it" in empty.output  # a usage error
    copy = tmp_path / "job"
    shutil.copytree(trained, copy)
    job = json.loads((copy / "job.json").read_text())
    plugin = {
        **job,
        "method": "nope",
        "method_ref": "olatbench.nope:Nope",
        "identity": {**job["identity"], "method": "nope"},
    }
    # a job of a plugin that is not installed here
    (copy / "job.json").write_text(json.dumps(plugin))
    unknown = runner.invoke(main, ["view", str(copy)])
    assert (
        unknown.exit_code == 1
        and "method 'nope' (olatbench.nope:Nope) cannot be imported" in unknown.output
    )
    (copy / "job.json").write_text(json.dumps(job))
    for checkpoint in (copy / "checkpoints").iterdir():
        checkpoint.unlink()
    unfinished = runner.invoke(main, ["view", str(tmp_path)])
    assert (
        unfinished.exit_code == 1 and "none of its 1 job folders can be shown" in unfinished.output
    )
    assert "no checkpoint" in unfinished.output


def test_record_a_light_orbit(trained, tmp_path, monkeypatch):
    from olatbench.datasets import suites

    # the run holds a tiny job
    other = CliRunner().invoke(main, ["view", str(trained.parents[4]), "-s", "mini"])
    # nothing to show
    assert other.exit_code == 1 and "no job with a checkpoint of suite mini" in other.output
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())
    out = tmp_path / "orbit.mp4"
    result = CliRunner().invoke(
        main,
        [
            "view",
            str(trained.parents[4]),
            "-s",
            "tiny",
            "--record",
            "light-orbit",
            str(out),
            "--frames",
            "3",
            "--component",
            "diffuse",
        ],
    )
    assert result.exit_code == 0, result.output
    capture = cv2.VideoCapture(str(out))
    count = 0
    while capture.read()[0]:
        count += 1
    capture.release()
    assert count == 3 and len(list((tmp_path / "orbit_frames").glob("*.png"))) == 3


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt-get install chromium)")
def test_the_page_shows_a_canvas_in_headless_chromium(app, tmp_path):
    """The page's JavaScript runs: after it loads, the DOM holds the WebGL canvas viser draws
    into."""
    # ANGLE's SwiftShader: software WebGL (Chromium 156 has none with the older --disable-gpu
    # --use-gl=swiftshader)
    result = subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--virtual-time-budget=15000",
            "--dump-dom",
            app.url,
        ],
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
    )
    assert "<canvas" in result.stdout, result.stderr[-2000:]


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt-get install chromium)")
def test_the_browser_latency_benchmark_times_light_moves_in_headless_chromium(trained):
    """benchmarks/bench_viewer_browser.py: two azimuth-slider drags in headless Chromium, each
    changing the image, timed from the mousemove to the painted preview and full-resolution
    image."""
    root = Path(__file__).resolve().parents[1]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")])),
    }
    result = subprocess.run(
        [
            sys.executable,
            str(root / "benchmarks" / "bench_viewer_browser.py"),
            str(trained),
            "--moves",
            "2",
            "--startup-timeout",
            str(int(BACKSTOP_SECONDS)),
        ],
        capture_output=True,
        text=True,
        timeout=2 * BACKSTOP_SECONDS,
        env=env,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    summary = [
        line
        for line in result.stdout.splitlines()
        if line.startswith("SUMMARY bench_viewer_browser ")
    ]
    fields = dict(field.split("=", 1) for field in summary[0].split()[2:])
    assert fields["moves"] == fields["valid"] == "2"
    assert 0 < float(fields["first_painted_ms"]) <= float(fields["full_painted_ms"])
    assert float(fields["full_arrived_ms"]) <= float(fields["full_painted_ms"])


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt-get install chromium)")
def test_the_environment_map_mode_converges_in_headless_chromium(trained, tmp_path):
    """benchmarks/viewer_envmap_browser.py: the lighting menu clicked to the environment map and the
    sky map, a camera drag during the refinement restarts it, the view converges to K samples, and
    the screenshot is written."""
    root = Path(__file__).resolve().parents[1]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")])),
    }
    shot = tmp_path / "envmap.png"
    result = subprocess.run(
        [
            sys.executable,
            str(root / "benchmarks" / "viewer_envmap_browser.py"),
            str(trained),
            "--out",
            str(shot),
            "--samples",
            "32",
            "--map",
            "sky",
            "--move-after",
            "12",
            "--startup-timeout",
            str(int(BACKSTOP_SECONDS)),
            "--timeout",
            str(int(BACKSTOP_SECONDS)),
        ],
        capture_output=True,
        text=True,
        timeout=2 * BACKSTOP_SECONDS,
        env=env,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "dragged the camera at" in result.stdout
    summary = [
        line
        for line in result.stdout.splitlines()
        if line.startswith("SUMMARY viewer_envmap_browser ")
    ]
    fields = dict(field.split("=", 1) for field in summary[0].split()[2:])
    assert fields["status"] == "ok" and fields["samples"] == "32" and fields["map"] == "sky"
    image = cv2.imread(str(shot))
    assert image is not None and image.shape[0] > 100 and image.std() > 1.0
