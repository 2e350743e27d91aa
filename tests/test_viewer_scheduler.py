"""The viewer's render scheduler and geometry, without a browser or a model."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from waiting import BACKSTOP_SECONDS, wait_until

from olatbench.datasets.cameras import intrinsics_from_fov, look_at
from olatbench.datasets.records import Camera
from olatbench.viewer.geometry import (
    LightFrame,
    browser_camera,
    camera_pose,
    matrix_to_quaternion,
    quaternion_to_matrix,
    render_size,
)
from olatbench.viewer.scheduler import RenderScheduler, Superseded


class ManualClock:
    """The scheduler's clock, moved by the test (seconds)."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Recorder:
    """A render function that records concurrency and can be held at a gate."""

    def __init__(self, seconds: float = 0.0) -> None:
        self.seconds = seconds
        self.lock = threading.Lock()
        self.active = 0
        self.max_active = 0
        self.gate = threading.Event()
        self.gate.set()
        self.started = threading.Event()
        self.delivered: list[tuple[object, object, str]] = []

    def render(self, request, quality):
        with self.lock:
            self.active += 1
            self.max_active = max(self.max_active, self.active)
        self.started.set()
        self.gate.wait(BACKSTOP_SECONDS)
        time.sleep(self.seconds)
        with self.lock:
            self.active -= 1
        return f"image of {request}"

    def deliver(self, key, request, image, quality):
        self.delivered.append((key, request, quality))


def test_one_render_in_flight_across_keys_and_threads():
    recorder = Recorder(seconds=0.002)
    with RenderScheduler(recorder.render, recorder.deliver, settle_seconds=0.0) as scheduler:

        def tab(key):
            for index in range(30):
                scheduler.submit(key, index)
                time.sleep(0.001)

        threads = [threading.Thread(target=tab, args=(key,)) for key in ("a", "b", "c")]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert recorder.max_active == 1
    last = {key: [r for k, r, q in recorder.delivered if k == key][-1] for key in ("a", "b", "c")}
    assert last == {"a": 29, "b": 29, "c": 29}  # every tab ends on its newest request


def test_requests_replaced_before_their_render_are_dropped_and_submit_never_blocks():
    recorder = Recorder()
    recorder.gate.clear()
    with RenderScheduler(recorder.render, recorder.deliver, settle_seconds=0.0) as scheduler:
        scheduler.submit("tab", 0)
        assert recorder.started.wait(BACKSTOP_SECONDS)  # request 0 is rendering, held at the gate
        ui = threading.Thread(
            target=lambda: [scheduler.submit("tab", index) for index in range(1, 10)]
        )
        ui.start()
        ui.join(BACKSTOP_SECONDS)
        # the UI thread is not held by the render in flight: its submits all returned while the gate
        # is shut
        assert not ui.is_alive() and not recorder.gate.is_set()
        recorder.gate.set()
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert [request for _, request, _ in recorder.delivered] == [0, 9]
    assert scheduler.dropped == 8


def test_progressive_previews_while_dragging_then_one_full_render_when_still():
    recorder = Recorder(seconds=0.005)
    # the scheduler's time: a busy machine cannot stretch the drag past the settle time
    clock = ManualClock()
    with RenderScheduler(
        recorder.render, recorder.deliver, settle_seconds=0.15, clock=clock
    ) as scheduler:
        for index in range(20):  # a drag: a new request every 10 ms, for 0.2 s
            scheduler.submit("tab", index)
            if index == 0:
                wait_until(lambda: recorder.delivered, "first preview", poll=0.001)
            clock.now += 0.01
        during = list(recorder.delivered)
        clock.now += 0.15  # the view stays still for the settle time
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert during and all(quality == "preview" for _, _, quality in during)
    assert recorder.delivered[-1] == ("tab", 19, "full")
    assert [q for _, _, q in recorder.delivered].count("full") == 1


def test_a_button_request_is_rendered_at_full_quality_at_once():
    recorder = Recorder()
    # the settle time never passes: only a render that does not wait for it can finish
    frozen = ManualClock()
    with RenderScheduler(
        recorder.render, recorder.deliver, settle_seconds=5.0, clock=frozen
    ) as scheduler:
        scheduler.submit("tab", "snap", progressive=False)
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert recorder.delivered == [("tab", "snap", "full")]


def test_render_errors_go_to_on_error_and_the_worker_goes_on():
    errors = []

    def render(request, quality):
        if request == "bad":
            raise ValueError("no such component")
        return request

    delivered = []
    with RenderScheduler(
        render,
        lambda key, request, image, quality: delivered.append(image),
        settle_seconds=0.0,
        on_error=lambda key, error: errors.append((key, str(error))),
    ) as scheduler:
        scheduler.submit("a", "bad")
        scheduler.submit("b", "good")
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert errors == [("a", "no such component")] and delivered == ["good"]


class Refiner:
    """A render function that refines: each pass of a request adds one to its count, and a pass
    stops early (as the viewer's environment-map passes do) when the scheduler says the request was
    superseded; passes can be held at a gate."""

    def __init__(self) -> None:
        self.scheduler: RenderScheduler | None = None
        self.passes: dict[object, int] = {}
        self.delivered: list[tuple[object, int, str]] = []  # (request, its pass count, quality)
        self.gate = threading.Semaphore(0)  # one release per pass allowed to finish
        self.cancelled_passes: list[object] = []
        self.started: list[object] = []  # each pass's request, once it waits at the gate

    def render(self, request, quality):
        self.started.append(request)
        if not self.gate.acquire(timeout=BACKSTOP_SECONDS):
            raise AssertionError("the test never released this pass")
        if quality == "full" and self.scheduler.superseded():
            self.cancelled_passes.append(request)
            raise Superseded()
        if quality == "full":
            self.passes[request] = self.passes.get(request, 0) + 1
        return self.passes.get(request, 0)

    def deliver(self, key, request, image, quality):
        self.delivered.append((request, image, quality))


def test_a_refining_request_gets_all_its_passes_and_a_newer_request_restarts_the_refinement():
    refiner = Refiner()
    with RenderScheduler(refiner.render, refiner.deliver, settle_seconds=0.0) as scheduler:
        refiner.scheduler = scheduler
        scheduler.submit("tab", "view A", progressive=False, passes=5)
        for _ in range(2):
            refiner.gate.release()
        wait_until(
            lambda: len(refiner.started) == 3, "A's third pass waiting at the gate", poll=0.001
        )
        assert len(refiner.delivered) == 2 and not scheduler.idle()
        # the camera moved during A's third pass
        scheduler.submit("tab", "view B", progressive=False, passes=3)
        for _ in range(4):  # A's pass in flight (it stops: superseded), then B's three
            refiner.gate.release()
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert refiner.delivered == [
        ("view A", 1, "full"),
        ("view A", 2, "full"),
        ("view B", 1, "full"),
        ("view B", 2, "full"),
        ("view B", 3, "full"),
    ]
    assert refiner.cancelled_passes == ["view A"] and scheduler.cancelled == 1


def test_refinement_passes_wait_for_the_view_to_be_still_and_a_preview_is_never_cancelled():
    refiner = Refiner()
    clock = ManualClock()
    with RenderScheduler(
        refiner.render, refiner.deliver, settle_seconds=0.15, clock=clock
    ) as scheduler:
        refiner.scheduler = scheduler
        scheduler.submit("tab", "moving", passes=3)
        scheduler.submit("tab", "moved", passes=3)  # arrives before the first preview starts
        refiner.gate.release()
        wait_until(lambda: refiner.delivered, "a preview", poll=0.001)
        assert refiner.delivered == [("moved", 0, "preview")] and not scheduler.idle()
        clock.now += 0.15
        for _ in range(3):
            refiner.gate.release()
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert [(request, count) for request, count, _ in refiner.delivered] == [
        ("moved", 0),
        ("moved", 1),
        ("moved", 2),
        ("moved", 3),
    ]
    assert scheduler.cancelled == 0


def test_a_failed_pass_ends_the_refinement_of_its_request():
    calls = []

    def render(request, quality):
        calls.append(request)
        raise ValueError("the map cannot be read")

    errors = []
    with RenderScheduler(
        render,
        lambda *args: None,
        settle_seconds=0.0,
        on_error=lambda key, error: errors.append(str(error)),
    ) as scheduler:
        scheduler.submit("tab", "view", progressive=False, passes=4)
        assert scheduler.wait_idle(BACKSTOP_SECONDS)
    assert calls == ["view"] and errors == ["the map cannot be read"]


def test_quaternions_match_scipy():
    for rotation in Rotation.random(20, random_state=1):
        x, y, z, w = rotation.as_quat()
        np.testing.assert_allclose(
            quaternion_to_matrix(np.array([w, x, y, z])), rotation.as_matrix(), atol=1e-12
        )
        q = matrix_to_quaternion(rotation.as_matrix())
        np.testing.assert_allclose(quaternion_to_matrix(q), rotation.as_matrix(), atol=1e-12)
        assert q[0] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-12


def test_browser_camera_reproduces_a_dataset_camera_from_its_pose():
    """A camera with square pixels and a centred principal point survives camera_pose ->
    browser_camera."""
    K = intrinsics_from_fov(np.radians(40.0), 64, 48)
    camera = Camera(K=K, c2w=look_at(np.array([3.0, -2.0, 1.5]), np.zeros(3)), width=64, height=48)
    wxyz, position, fov = camera_pose(camera)
    again = browser_camera(wxyz, position, fov, 64, 48)
    np.testing.assert_allclose(again.K, camera.K, atol=1e-9)
    np.testing.assert_allclose(again.c2w, camera.c2w, atol=1e-12)
    assert render_size((64, 48), 512) == (64, 48) and render_size((64, 48), 512, 0.5) == (32, 24)
    assert render_size((1280, 640), 512) == (512, 256) and render_size((640, 1280), 512, 0.5) == (
        128,
        256,
    )
    assert render_size((10, 10), 512, 0.05) == (8, 8)


def test_light_frame_spherical_coordinates():
    frame = LightFrame.of(
        np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 2.0]), np.array([4.0, 2.0, 7.0])
    )
    np.testing.assert_allclose(frame.forward, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(frame.position(0.0, 0.0, 2.0), [3.0, 2.0, 3.0])
    # counter-clockwise
    np.testing.assert_allclose(frame.position(90.0, 0.0, 2.0), [1.0, 4.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(frame.position(0.0, 90.0, 2.0), [1.0, 2.0, 5.0], atol=1e-12)
    for azimuth, elevation, distance in (
        (-170.0, 10.0, 0.5),
        (35.0, -60.0, 3.0),
        (120.0, 80.0, 1.0),
    ):
        position = frame.position(azimuth, elevation, distance)
        assert frame.spherical(position) == pytest.approx((azimuth, elevation, distance))


def test_environment_settings_errors_are_one_line_naming_the_field(tmp_path):
    from olatbench.viewer.environment import (
        SettingsError,
        map_menu,
        parse_settings,
        refinement_passes,
    )

    menu = map_menu()
    assert list(menu) == ["studio", "sky", "furnace"]
    settings = parse_settings(menu, "sky", 30, "-1.5", 16.0)
    assert (settings.source, settings.rotation, settings.exposure, settings.samples) == (
        "sky",
        30.0,
        -1.5,
        16,
    )
    bad = {
        "map 'attic'": ("attic", 0, 0, 64),
        "map '/etc/passwd'": ("/etc/passwd", 0, 0, 64),
        "rotation °": ("sky", float("nan"), 0, 64),
        "exposure (stops)": ("sky", 0, "bright", 64),
        "samples: 0": ("sky", 0, 0, 0),
        "samples: 2.5": ("sky", 0, 0, 2.5),
        "samples: 100000": ("sky", 0, 0, 1e5),
    }
    for field, values in bad.items():
        with pytest.raises(SettingsError) as caught:
            parse_settings(menu, *values)
        message = str(caught.value)
        assert message.startswith(field) and "\n" not in message, message
    broken = tmp_path / "broken.exr"
    broken.write_bytes(b"not an image")
    for path, says in (
        (tmp_path / "room.png", "an .exr or .hdr file"),
        (tmp_path / "missing.exr", "not found"),
        (broken, str(broken)),
    ):
        with pytest.raises(SettingsError) as caught:
            map_menu([path])
        message = str(caught.value)
        assert message.startswith(f"--envmap {path}") and says in message and "\n" not in message, (
            message
        )
    assert [refinement_passes(k, 4, 8) for k in (1, 4, 5, 12, 13, 64)] == [1, 1, 2, 2, 3, 9]
    from olatbench.datasets.images import write_image

    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        write_image(tmp_path / folder / "room.exr", np.full((4, 8, 3), 0.5, dtype=np.float32))
    write_image(tmp_path / "hall.hdr", np.full((4, 8, 3), 0.5, dtype=np.float32))
    menu = map_menu(
        [tmp_path / "a" / "room.exr", tmp_path / "b" / "room.exr", tmp_path / "hall.hdr"]
    )
    # two files named alike: by path
    assert menu == {
        "studio": "studio",
        "sky": "sky",
        "furnace": "furnace",
        str(tmp_path / "a" / "room.exr"): str(tmp_path / "a" / "room.exr"),
        str(tmp_path / "b" / "room.exr"): str(tmp_path / "b" / "room.exr"),
        "hall.hdr": str(tmp_path / "hall.hdr"),
    }
    # the file is sampled
    assert parse_settings(menu, "hall.hdr", 0, 0, 8).lighting().sample().directions
