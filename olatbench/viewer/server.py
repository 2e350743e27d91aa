"""The viser application: one `ClientSession` per browser tab, all rendering through one
`RenderScheduler`.

Each tab has its own camera, light, output and GUI (viser's per-client ``client.gui`` /
``client.scene``), so tabs do not disturb one another; they share the restored models and the one
render worker. The browser orbits, pans and zooms its camera itself; every camera, light or output
change submits a request for that tab, which the scheduler renders at reduced resolution while
changes keep coming and at the browser canvas's size (its longer side capped at ``max_resolution``)
once they stop, then sends as the tab's background image (JPEG). Snapping to a dataset frame renders
it with the frame's own camera and light, beside its ground truth and PSNR (lossless PNG in the GUI
panel).

A tab's *lighting* menu switches between the point light and an environment map
(`olatbench.viewer.environment`): while the view moves, each image is the map's estimate from
``preview_samples`` of its ``K`` samples at the drag resolution; once still, the full-resolution
image is refined pass by pass (``preview_samples`` first, then ``batch_samples`` more per pass, each
image the average so far: `olatbench.bench.progressive`) until it is the ``K``-sample relight
``olatbench render --envmap`` makes; a camera move or a changed setting supersedes it at the next
sample (`RenderScheduler.superseded`) and the refinement starts again.

A job still training is followed: every ``follow_seconds`` a follower thread restores the newest
checkpoint of each shown job that has not finished, when the runner has written a newer one, and
every tab showing it renders again.
"""

from __future__ import annotations

import functools
import threading
import time
import traceback
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.bench.progressive import ProgressiveRelight
from olatbench.bench.restore import RestoreError
from olatbench.datasets.records import PointLight
from olatbench.viewer.environment import (
    BATCH_SAMPLES,
    DEFAULT_SAMPLES,
    ENVIRONMENT_MODE,
    EXPOSURE_RANGE,
    MAX_SAMPLES,
    MODES,
    POINT_MODE,
    PREVIEW_SAMPLES,
    ROTATION_RANGE,
    EnvironmentSettings,
    SettingsError,
    map_menu,
    parse_settings,
    pass_size,
    refinement_passes,
)
from olatbench.viewer.geometry import MAX_RESOLUTION, browser_camera, camera_pose, render_size
from olatbench.viewer.model import Comparison, ViewerFrame, ViewerModel
from olatbench.viewer.scheduler import Quality, RenderScheduler, Superseded

JPEG_QUALITY = 90
MAX_MODELS = 4  # restored models kept at once; the least recently chosen goes first
LIGHT_COLOUR = (255, 210, 60)
CAMERA_COLOUR = (60, 120, 220)


@dataclass(frozen=True)
class ViewRequest:
    """Render ``component`` of ``model`` from a browser pose (OpenCV camera-to-world ``wxyz`` and
    ``position``, vertical ``fov`` in radians) for a browser ``canvas`` of (width, height) pixels
    under ``light``."""

    model: ViewerModel
    wxyz: tuple[float, ...]
    position: tuple[float, ...]
    fov: float
    canvas: tuple[int, int]
    light: PointLight
    component: str


@dataclass
class Refinement:
    """How far an environment-map request has been refined at full resolution: its progressive
    relight and the checkpoint step of the model drawing it (set and advanced by the render worker
    only)."""

    relight: ProgressiveRelight | None = None
    step: int = 0


@dataclass(frozen=True, eq=False)
class EnvironmentRequest:
    """Render ``model`` from a browser pose (as `ViewRequest`) under an environment map's
    ``settings``; the scheduler renders it once as a preview and then refines it pass by pass
    (``refinement``)."""

    model: ViewerModel
    wxyz: tuple[float, ...]
    position: tuple[float, ...]
    fov: float
    canvas: tuple[int, int]
    settings: EnvironmentSettings
    refinement: Refinement = field(default_factory=Refinement)
    component: str = "rgb"  # only rgb adds up over lights


@dataclass(frozen=True)
class CompareRequest:
    """Render a dataset frame with its own camera and light beside its ground truth."""

    model: ViewerModel
    frame: ViewerFrame


@dataclass(frozen=True)
class Delivered:
    """The newest image a tab received: what was asked, the (H, W, 3) uint8 image, its quality,
    render time, the checkpoint step of the model that drew it and, under an environment map,
    (samples averaged, of ``K``)."""

    request: ViewRequest | EnvironmentRequest
    image: np.ndarray
    quality: Quality
    seconds: float
    step: int
    samples: tuple[int, int] | None = None


class ViewerApp:
    """The viewer over one or more job folders (the first restored eagerly by the caller, the others
    on demand).

    Renders fill the browser canvas, their longer side capped at ``max_resolution`` pixels;
    ``drag_scale`` is the resolution factor while the user drags (1.0: always full);
    ``settle_seconds`` how long a view must be still before its full-resolution render;
    ``follow_seconds`` how often jobs still training are checked for a newer checkpoint;
    ``max_models`` how many restored models are kept (a tab keeps showing its model after the cache
    lets go of it). ``maps`` is the environment-map menu (label -> source,
    `olatbench.viewer.environment.map_menu`; default the built-in maps), ``samples`` the ``K`` a tab
    starts with, ``preview_samples`` and ``batch_samples`` the samples of the moving view's image
    and of each refinement pass.

    Only the listed ``folders`` are ever opened: a tab chooses among them by name (`listed`), so a
    browser cannot make the server read another path, even when it is reachable from other machines
    (``--host 0.0.0.0``).
    """

    def __init__(
        self,
        folders: list[Path],
        first: ViewerModel,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        device: str = "cpu",
        drag_scale: float = 0.5,
        settle_seconds: float = 0.25,
        max_resolution: int = MAX_RESOLUTION,
        follow_seconds: float = 2.0,
        verbose: bool = False,
        max_models: int = MAX_MODELS,
        maps: dict[str, str] | None = None,
        samples: int = DEFAULT_SAMPLES,
        preview_samples: int = PREVIEW_SAMPLES,
        batch_samples: int = BATCH_SAMPLES,
    ) -> None:
        self.folders = [Path(f) for f in folders]
        self.host, self.port, self.device, self.verbose = host, port, device, verbose
        self.drag_scale, self.max_resolution = drag_scale, max_resolution
        self.max_models = max(1, max_models)
        self.maps = map_menu() if maps is None else dict(maps)
        self.samples, self.preview_samples, self.batch_samples = (
            samples,
            preview_samples,
            batch_samples,
        )
        self._models: OrderedDict[Path, ViewerModel] = OrderedDict({self.folders[0]: first})
        self._models_lock = threading.Lock()
        self.sessions: dict[int, ClientSession] = {}
        self.scheduler = RenderScheduler(
            self._render, self._deliver, settle_seconds=settle_seconds, on_error=self._render_failed
        )
        self.follow_seconds = follow_seconds
        self._stopping = threading.Event()
        self._follower = threading.Thread(
            target=self._follow, name="olatbench-viewer-follow", daemon=True
        )
        self.server: Any = None

    # -------------------------------------------------------------------------------------------
    # lifecycle
    def start(self) -> ViewerApp:
        import viser

        self.scheduler.start()
        self.server = viser.ViserServer(
            host=self.host, port=self.port, label="olatbench view", verbose=self.verbose
        )
        self.port = self.server.get_port()
        self.server.gui.configure_theme(control_width="large")
        first = self.model(self.folders[0])
        self.server.scene.set_up_direction(tuple(first.light_frame.up))
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)
        self._follower.start()
        return self

    def stop(self) -> None:
        self._stopping.set()
        if self._follower.is_alive():
            self._follower.join(10.0)
        if self.server is not None:
            self.server.stop()
        self.scheduler.close()

    def __enter__(self) -> ViewerApp:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def listed(self, choice: str | Path) -> Path:
        """The listed job folder named ``choice`` (as the job menu writes it); a `ValueError` for
        any other."""
        for folder in self.folders:
            if str(folder) == str(choice):
                return folder
        raise ValueError("not one of the jobs this viewer serves")

    def model(self, folder: str | Path) -> ViewerModel:
        """The restored model of a listed job folder (`listed`): restored on first use, then kept
        while it is among the ``max_models`` most recently used."""
        folder = self.listed(folder)
        with self._models_lock:
            if folder not in self._models:
                self._models[folder] = ViewerModel.open(folder, self.device)
            self._models.move_to_end(folder)
            while len(self._models) > self.max_models:
                self._models.popitem(last=False)
            return self._models[folder]

    def _follow(self) -> None:
        """Until `stop`: reload the jobs still training when they have a newer checkpoint; re-render
        their tabs."""
        while not self._stopping.wait(self.follow_seconds):
            # the cached models and those tabs still show after the cache let them go
            with self._models_lock:
                shown = {id(model): model for model in self._models.values()}
            shown.update(
                {
                    id(session.model): session.model
                    for session in list(self.sessions.values())
                    if getattr(session, "model", None) is not None
                }
            )
            training = [model for model in shown.values() if not model.finished]
            for model in training:
                try:
                    reloaded = model.reload_if_newer()
                except RestoreError as error:
                    for session in list(self.sessions.values()):
                        if session.model is model:
                            session.status.content = f"**cannot follow {model.label}**: {error}"
                    continue
                if reloaded:
                    for session in list(self.sessions.values()):
                        if session.model is model:
                            session.refresh()

    def _connect(self, client: Any) -> None:
        # registers itself in `sessions` before it sends anything to the tab
        ClientSession(self, client)

    def _disconnect(self, client: Any) -> None:
        self.sessions.pop(client.client_id, None)
        for kind in ("view", "compare"):
            self.scheduler.forget((client.client_id, kind))

    # -------------------------------------------------------------------------------------------
    # rendering
    def _render(
        self, request: ViewRequest | EnvironmentRequest | CompareRequest, quality: Quality
    ) -> tuple[Any, float, int, tuple[int, int] | None]:
        """(image or comparison, seconds, checkpoint step, (samples averaged, K) under an
        environment map)."""
        started = time.perf_counter()
        if isinstance(request, CompareRequest):
            return (
                request.model.compare(request.frame),
                time.perf_counter() - started,
                request.model.step,
                None,
            )
        size = render_size(
            request.canvas, self.max_resolution, 1.0 if quality == "full" else self.drag_scale
        )
        camera = browser_camera(
            np.asarray(request.wxyz), np.asarray(request.position), request.fov, *size
        )
        if isinstance(request, EnvironmentRequest):
            image, step, samples = self._refine(request, camera, quality)
            return image, time.perf_counter() - started, step, samples
        image, step = request.model.render_with_step(camera, request.light, request.component)
        return image, time.perf_counter() - started, step, None

    def _refine(
        self, request: EnvironmentRequest, camera: Any, quality: Quality
    ) -> tuple[np.ndarray, int, tuple[int, int]]:
        """A preview (a fresh relight of the moving view at ``preview_samples``) or the next
        refinement pass of the still view; a pass whose request is superseded stops at the next
        sample (`Superseded`)."""
        if quality == "preview":  # short: always finished and shown, so that a drag shows images
            relight, step = request.model.progressive(camera, request.settings)
            image = request.model.refine(relight, self.preview_samples)
            if image is None:
                raise ValueError("an environment map preview needs at least one sample")
        else:
            refinement = request.refinement
            if refinement.relight is None:
                refinement.relight, refinement.step = request.model.progressive(
                    camera, request.settings
                )
            relight, step = refinement.relight, refinement.step
            image = request.model.refine(
                relight,
                pass_size(relight.done, self.preview_samples, self.batch_samples),
                self.scheduler.superseded,
            )
            if image is None or self.scheduler.superseded():
                raise Superseded()
        # in map samples: a light-blind method's one render stands for all K
        return (
            image,
            step,
            (relight.done * request.settings.samples // relight.total, request.settings.samples),
        )

    def _deliver(
        self, key: Hashable, request: Any, result: tuple[Any, float, int, Any], quality: Quality
    ) -> None:
        session = self.sessions.get(key[0])
        if session is not None:
            session.show(request, result[0], quality, result[1], result[2], result[3])

    def _render_failed(self, key: Hashable, error: BaseException) -> None:
        session = self.sessions.get(key[0])
        text = f"{type(error).__name__}: {error}"
        if self.verbose:
            traceback.print_exception(error)
        if session is not None:
            session.status.content = f"**render failed**: {text}"


def _locked(method: Callable[..., None]) -> Callable[..., None]:
    """Run a `ClientSession` method under the session's lock."""

    @functools.wraps(method)
    def locked(self: ClientSession, *args: Any, **kwargs: Any) -> None:
        with self._lock:
            method(self, *args, **kwargs)

    return locked


def _camera_state_received(camera: Any) -> bool:
    """Whether viser has received a camera message from the tab yet (its handle's private state has
    a timestamp: the public accessors assert on it)."""
    state = getattr(camera, "_state", None)
    return bool(getattr(state, "update_timestamp", 0.0))


class ClientSession:
    """One browser tab: its model, camera pose, light, output, GUI and scene nodes."""

    def __init__(self, app: ViewerApp, client: Any) -> None:
        self.app, self.client = app, client
        self.delivered: Delivered | None = None
        self.comparison: Comparison | None = None
        self.pose: tuple[tuple[float, ...], tuple[float, ...], float] | None = None
        self.canvas = (1, 1)  # the browser canvas (width, height) in pixels, once the tab has said
        self._camera_known = False
        self._scene_nodes: list[Any] = []
        # Events of the tab (run on viser's thread pool) and public calls wait while another one, or
        # the set-up, changes the session: the set-up already sends GUI and scene messages, so the
        # tab can answer early.
        self._lock = threading.RLock()
        with self._lock:
            app.sessions[client.client_id] = self
            self._build_gui()
            self.use_model(app.model(app.folders[0]))
            client.camera.on_update(self._camera_moved)
            # viser runs this set-up in a thread pool beside the connection, so the tab's first
            # camera message often arrives before the handler exists and reaches nobody; answer it
            # here. A message arriving after the registration waits for the lock and is handled as
            # an ordinary move; one arriving between the registration and this check is handled
            # twice, the second time as a move to where the tab still is, which the tab's next
            # message (after the move to the home frame) supersedes.
            if _camera_state_received(client.camera):
                self._camera_moved(client.camera)

    # -------------------------------------------------------------------------------------------
    # GUI
    def _build_gui(self) -> None:
        gui = self.client.gui
        self.status = gui.add_markdown("connecting…")
        if len(self.app.folders) > 1:
            self.job_dropdown = gui.add_dropdown(
                "job", [str(f) for f in self.app.folders], initial_value=str(self.app.folders[0])
            )
            self.job_dropdown.on_update(self._job_chosen)
        self.mode = gui.add_dropdown("lighting", MODES, initial_value=POINT_MODE)
        self.mode.on_update(self._mode_chosen)
        # the valid settings of the environment-map controls
        self.environment: EnvironmentSettings | None = None
        self.env_folder = gui.add_folder("Environment map", visible=False)
        with self.env_folder:
            self.env_map = gui.add_dropdown(
                "map", list(self.app.maps), initial_value=next(iter(self.app.maps))
            )
            self.env_rotation = gui.add_slider("rotation °", *ROTATION_RANGE, 1.0, 0.0)
            self.env_exposure = gui.add_slider("exposure (stops)", *EXPOSURE_RANGE, 0.25, 0.0)
            self.env_samples = gui.add_number(
                "samples", self.app.samples, min=1, max=MAX_SAMPLES, step=1
            )
        self.env_map.on_update(lambda event: self._environment_changed(event, progressive=False))
        for control in (self.env_rotation, self.env_exposure):
            control.on_update(self._environment_changed)
        self.env_samples.on_update(
            lambda event: self._environment_changed(event, progressive=False)
        )
        self.light_folder = gui.add_folder("Light")
        with self.light_folder:
            self.azimuth = gui.add_slider("azimuth °", -180.0, 180.0, 1.0, 0.0)
            self.elevation = gui.add_slider("elevation °", -89.0, 89.0, 1.0, 0.0)
            self.distance = gui.add_slider("distance", 0.01, 1.0, 0.01, 0.5)
            self.intensity = gui.add_slider("intensity ×", 0.0, 4.0, 0.05, 1.0)
        for slider in (self.azimuth, self.elevation, self.distance):
            slider.on_update(self._light_slid)
        self.intensity.on_update(self._intensity_slid)
        with gui.add_folder("Output"):
            self.output = gui.add_dropdown("component", ["rgb"], initial_value="rgb")
            self.output.on_update(self._output_chosen)
        with gui.add_folder("Dataset frames"):
            self.frame_dropdown = gui.add_dropdown("frame", ["-"], initial_value="-")
            self.snap_button = gui.add_button("Snap camera and light to frame")
            self.snap_button.on_click(self._snap_clicked)
            self.comparison_text = gui.add_markdown(
                "Snap to a frame to see its ground truth and PSNR."
            )
            self.comparison_image = gui.add_image(
                np.zeros((8, 16, 3), np.uint8),
                label="render | ground truth",
                format="png",
                visible=False,
            )
            self.show_cameras = gui.add_checkbox("training cameras", False)
            self.show_lights = gui.add_checkbox("training lights", False)
        self.show_cameras.on_update(lambda _: self._set_visible("cameras", self.show_cameras.value))
        self.show_lights.on_update(lambda _: self._set_visible("lights", self.show_lights.value))

    @_locked
    def use_model(self, model: ViewerModel) -> None:
        """Show ``model``: GUI options, scene nodes (light handle, training cameras and lights), its
        home frame."""
        self.model = model
        self.frame_dropdown.options = [f.label for f in model.frames]
        self.frame_dropdown.value = model.home.label
        self.output.options = list(model.components)
        self.output.value = "rgb" if "rgb" in model.components else model.components[0]
        light_frame = model.light_frame
        home_distance = light_frame.spherical(model.home.light.position)[2]
        extent = max(
            float(np.linalg.norm(f.camera.position - light_frame.centre)) for f in model.train
        )
        limit = max(3.0 * home_distance, 1.5 * extent)
        self.distance.max = round(limit, 2)
        self.distance.step = max(round(limit / 300, 3), 0.001)
        self.base_intensity = np.asarray(model.home.light.intensity, dtype=np.float64)
        self.light_template = model.home.light
        for node in self._scene_nodes:
            node.remove()
        scene = self.client.scene
        self.light_handle = scene.add_transform_controls(
            "/light",
            scale=0.15 * home_distance,
            disable_rotations=True,
            position=tuple(model.home.light.position),
        )
        self.light_handle.on_update(self._light_dragged)
        scene.add_icosphere("/light/bulb", radius=0.02 * home_distance, color=LIGHT_COLOUR)
        self.cameras = [
            scene.add_camera_frustum(
                f"/train/cameras/{index}",
                fov=camera_pose(f.camera)[2],
                aspect=f.camera.width / f.camera.height,
                scale=0.05 * extent,
                wxyz=camera_pose(f.camera)[0],
                position=camera_pose(f.camera)[1],
                color=CAMERA_COLOUR,
                visible=bool(self.show_cameras.value),
            )
            for index, f in enumerate(model.train)
        ]
        self.lights = scene.add_point_cloud(
            "/train/lights",
            np.array([f.light.position for f in model.train], dtype=np.float32),
            colors=LIGHT_COLOUR,
            point_size=0.01 * extent,
            visible=bool(self.show_lights.value),
        )
        # the bulb goes with /light
        self._scene_nodes = [self.light_handle, *self.cameras, self.lights]
        self._set_mode(str(self.mode.value))  # the new handle's visibility
        self.snap(model.home, compare=False)

    def _set_visible(self, kind: str, visible: bool) -> None:
        for node in self.cameras if kind == "cameras" else [self.lights]:
            node.visible = visible

    # -------------------------------------------------------------------------------------------
    # state
    @property
    def light(self) -> PointLight:
        """The light the tab renders with: the handle's position, the home light's intensity × the
        slider."""
        return replace(
            self.light_template,
            position=np.asarray(self.light_handle.position, dtype=np.float64),
            intensity=self.base_intensity * float(self.intensity.value),
        )

    @_locked
    def set_light(self, position: np.ndarray) -> None:
        """Move the light (handle and sliders) and render."""
        self.light_handle.position = tuple(float(v) for v in position)
        self._sync_sliders()
        self.request()

    def _sync_sliders(self) -> None:
        azimuth, elevation, distance = self.model.light_frame.spherical(
            np.asarray(self.light_handle.position)
        )
        self.azimuth.value = round(azimuth, 1)
        self.elevation.value = round(max(-89.0, min(89.0, elevation)), 1)
        self.distance.value = min(round(distance, 3), self.distance.max)

    @_locked
    def snap(self, frame: ViewerFrame, compare: bool = True) -> None:
        """Camera and light to a dataset frame; with ``compare`` (back to the point-light mode, the
        frame's), render it beside its ground truth."""
        if compare:
            self._set_mode(POINT_MODE)
        wxyz, position, fov = camera_pose(frame.camera)
        self.pose = (tuple(wxyz), tuple(position), fov)
        self.canvas = (
            (frame.camera.width, frame.camera.height) if not self._camera_known else self.canvas
        )
        self.intensity.value = 1.0
        if self._camera_known:
            self._move_browser_camera(frame)
        self.set_light(np.asarray(frame.light.position, dtype=np.float64))
        if compare:
            self.app.scheduler.submit(
                (self.client.client_id, "compare"),
                CompareRequest(self.model, frame),
                progressive=False,
            )

    def _move_browser_camera(self, frame: ViewerFrame) -> None:
        camera = self.client.camera
        c2w = frame.camera.c2w
        centre = self.model.light_frame.centre
        with self.client.atomic():
            camera.fov = camera_pose(frame.camera)[2]
            camera.up_direction = tuple(-c2w[:3, 1])
            camera.position = tuple(c2w[:3, 3])
            camera.look_at = tuple(
                c2w[:3, 3] + c2w[:3, 2] * float(np.linalg.norm(centre - c2w[:3, 3]))
            )

    @_locked
    def refresh(self) -> None:
        """Render the current state again at full resolution (the model changed: a newer
        checkpoint)."""
        self.request(progressive=False)

    def request(self, progressive: bool = True) -> None:
        """Submit a render of the current state (never blocks)."""
        if self.pose is None:
            return
        wxyz, position, fov = self.pose
        key = (self.client.client_id, "view")
        if self.mode.value == ENVIRONMENT_MODE and self.environment is not None:
            # a light-blind method: one render
            total = self.environment.samples if self.model.relightable else 1
            self.app.scheduler.submit(
                key,
                EnvironmentRequest(self.model, wxyz, position, fov, self.canvas, self.environment),
                progressive,
                refinement_passes(total, self.app.preview_samples, self.app.batch_samples),
            )
            return
        self.app.scheduler.submit(
            key,
            ViewRequest(
                self.model, wxyz, position, fov, self.canvas, self.light, str(self.output.value)
            ),
            progressive,
        )

    def _set_mode(self, mode: str) -> None:
        """Show ``mode`` (`MODES`): the light's folder, handle and the output menu go with the point
        light, the environment map's folder with the map."""
        self.mode.value = mode
        point = mode == POINT_MODE
        self.light_handle.visible = self.light_folder.visible = point
        self.env_folder.visible = not point
        self.output.disabled = not point

    # -------------------------------------------------------------------------------------------
    # events
    @_locked
    def _camera_moved(self, camera: Any) -> None:
        if camera.image_height and camera.image_width:
            self.canvas = (int(camera.image_width), int(camera.image_height))
        if not self._camera_known:  # the first message of the tab: show the home frame
            self._camera_known = True
            self._move_browser_camera(self.model.home)
            self.request(progressive=False)
            return
        self.pose = (tuple(camera.wxyz), tuple(camera.position), float(camera.fov))
        self.request()

    @_locked
    def _light_dragged(self, event: Any) -> None:
        self._sync_sliders()
        self.request()

    @_locked
    def _light_slid(self, event: Any) -> None:
        if event.client is None:  # set by the server (sliders follow the handle), not by the user
            return
        position = self.model.light_frame.position(
            float(self.azimuth.value), float(self.elevation.value), float(self.distance.value)
        )
        self.light_handle.position = tuple(float(v) for v in position)
        self.request()

    @_locked
    def _intensity_slid(self, event: Any) -> None:
        if event.client is not None:
            self.request()

    @_locked
    def _output_chosen(self, event: Any) -> None:
        if event.client is not None:
            self.request(progressive=False)

    @_locked
    def _mode_chosen(self, event: Any) -> None:
        if event.client is None:
            return
        mode = self.mode.value
        if mode not in MODES:  # the tab sends the value
            self.status.content = f"**lighting**: {mode!r} is not one of {', '.join(MODES)}"
            return
        if mode == ENVIRONMENT_MODE and not self._read_environment():
            return
        self._set_mode(mode)
        self.request(progressive=False)

    @_locked
    def _environment_changed(self, event: Any, progressive: bool = True) -> None:
        if (
            event.client is not None
            and self._read_environment()
            and self.mode.value == ENVIRONMENT_MODE
        ):
            self.request(progressive)

    def _read_environment(self) -> bool:
        """Take the environment controls' values as the settings; whether they are valid (else the
        status says why in one line, and the last valid settings stay)."""
        try:
            self.environment = parse_settings(
                self.app.maps,
                self.env_map.value,
                self.env_rotation.value,
                self.env_exposure.value,
                self.env_samples.value,
            )
        except SettingsError as error:
            self.status.content = f"**environment map**: {error}"
            return False
        return True

    @_locked
    def _snap_clicked(self, event: Any) -> None:
        # the tab sends the name: one that is not in the list is said there, not raised on the
        # server
        try:
            frame = self.model.frame(str(self.frame_dropdown.value))
        except KeyError as error:
            self.status.content = f"**cannot snap**: {error.args[0]}"
            return
        self.snap(frame)

    @_locked
    def _job_chosen(self, event: Any) -> None:
        if event.client is None:
            return
        try:
            # the tab sends the value: only listed ones
            folder = self.app.listed(str(self.job_dropdown.value))
        except ValueError as error:
            self.status.content = f"**cannot show the chosen job**: {error}"
            return
        self.status.content = f"restoring {folder} …"
        try:
            self.use_model(self.app.model(folder))
        except Exception as error:  # shown in the tab; the other jobs stay usable
            self.status.content = f"**cannot show {folder}**: {error}"

    # -------------------------------------------------------------------------------------------
    # output
    def show(
        self,
        request: Any,
        result: Any,
        quality: Quality,
        seconds: float,
        step: int,
        samples: tuple[int, int] | None = None,
    ) -> None:
        """Put a finished render in the tab (called on the render worker)."""
        if isinstance(request, CompareRequest):
            self.comparison = result
            self.comparison_image.image = np.concatenate(
                [result.render, result.ground_truth], axis=1
            )
            self.comparison_image.visible = True
            recorded = (
                f" (runner: {result.recorded_psnr:.2f} dB)"
                if result.recorded_psnr is not None
                else ""
            )
            self.comparison_text.content = (
                f"**{result.frame.label}**: PSNR {result.psnr:.2f} dB{recorded}"
            )
            return
        # before it leaves: tests wait
        self.delivered = Delivered(request, result, quality, seconds, step, samples)
        self.client.scene.set_background_image(result, format="jpeg", jpeg_quality=JPEG_QUALITY)
        height, width = result.shape[:2]
        state = "full" if quality == "full" else "dragging"
        if samples is None:
            what = request.component
        else:
            what = f"{request.settings.label} · {samples[0]}/{samples[1]} samples"
            state = (
                "moving"
                if quality == "preview"
                else "converged"
                if samples[0] == samples[1]
                else "refining"
            )
        self.status.content = (
            f"{self.model.label} · {what} · {width}×{height} ({state}) in {1000 * seconds:.0f} ms"
        )
