"""Assembles the daemon from settings: cameras, detector, MoM model, pipeline, hub; runs uvicorn.

``momloc serve`` and ``momloc demo`` differ only in the settings they pass here, so the demo
exercises exactly the code users run on real cameras.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from models.detector.windows import WindowRefiner
from models.errors import MomlocError
from service.hub import Hub
from service.model_watch import ModelWatcher
from service.pipeline import DetectorStage, Pipeline
from service.settings import FileCamera, Settings, SyntheticCamera, V4l2Camera
from service.setup.camera_monitor import CameraMoved
from service.setup.session import SetupSession

log = logging.getLogger("momloc")
GRACEFUL_SHUTDOWN_S = 3


@dataclass
class Daemon:
    """Everything the API reads: hub, pipeline and the static facts about the setup."""

    hub: Hub
    pipeline: Pipeline
    camera_names: list[str]
    token: str | None = None
    stream_rate: float = 30.0
    ping_interval: float = 20.0
    ping_timeout: float = 20.0
    floor: dict[str, float] | None = None
    extras: dict[str, Any] = field(default_factory=dict)
    started: float = field(default_factory=time.time)
    watcher: ModelWatcher | None = None
    setup: SetupSession | None = None
    bind_host: str = "127.0.0.1"  # with the two lists below: see service.request_guard
    allowed_hosts: list[str] = field(default_factory=list)
    allowed_origins: list[str] = field(default_factory=list)
    outputs: Any = None  # service.outputs.Outputs: zones, MQTT

    def camera_states(self) -> list[dict[str, Any]]:
        states = self.pipeline.rig.states()
        alignment = self.pipeline.alignment_status(self.camera_names)
        out = []
        for k, state in enumerate(states):
            d = dataclasses.asdict(state) if dataclasses.is_dataclass(state) else dict(vars(state))
            d = {
                "index": k,
                "name": self.camera_names[k] if k < len(self.camera_names) else f"camera-{k}",
                "connected": bool(d.get("connected", False)),
                "fps": _round(d.get("fps")),
                "last_frame_age": _round(d.get("last_frame_age"), 3),
                "reconnects": int(d.get("reconnects") or 0),
                "error": d.get("error"),
                "alignment": _alignment(alignment[k]) if k < len(alignment) else None,
            }
            out.append(d)
        return out

    def health(self) -> dict[str, Any]:
        cameras = self.camera_states()
        model = self.pipeline.model_info()
        pipeline = self.pipeline.stats()
        ok = (
            all(c["connected"] and not (c["alignment"] or {}).get("moved") for c in cameras)
            and model["loaded"]
            and model.get("compatible", False)
            and pipeline["running"]
            and pipeline["error"] is None
        )
        return {
            "status": "ok" if ok else "degraded",
            "uptime_s": round(time.time() - self.started, 1),
            "cameras": cameras,
            "model": model,
            "pipeline": pipeline,
            "clients": self.hub.subscriber_count,
            "stream": self.hub.stream_stats(),
            "model_reload": None if self.watcher is None else self.watcher.last_reload,
            **({} if self.outputs is None else self.outputs.health()),
            **self.extras,
        }

    def public_config(self) -> dict[str, Any]:
        return {
            "cameras": [{"index": k, "name": n} for k, n in enumerate(self.camera_names)],
            "floor": self.floor,
            "stream_rate": self.stream_rate,
            "auth": self.token is not None,
            "zones": []
            if self.outputs is None
            else [z.as_dict() for z in self.outputs.zones.zones],
            **self.extras,
        }


def _alignment(state: CameraMoved) -> dict[str, Any]:
    """The camera-moved check as health JSON: image shift and reprojection error, what to do."""
    shift, error = state.shift, state.reprojection
    return {
        "moved": state.moved,
        "shift_px": _round(shift.shift_px, 1),
        "shift_confidence": _round(shift.confidence),
        "reference": shift.reference,
        "shift_moved": shift.moved,
        "reprojection_px": _round(error.error_px, 1),
        "usual_px": _round(error.baseline_px, 1),
        "reprojection_moved": error.moved,
        "message": state.message,
    }


def _round(value: Any, digits: int = 2) -> float | None:
    return None if value is None else round(float(value), digits)


def camera_name(camera: Any) -> str:
    if camera.name:
        return camera.name
    if isinstance(camera, V4l2Camera):
        return camera.device
    if isinstance(camera, FileCamera):
        return camera.path.name
    return f"synthetic-{camera.index}"


def build_rig(settings: Settings) -> tuple[Any, Any]:
    """The camera rig for ``settings.cameras`` and, for synthetic scenes, the scene player."""
    kinds = {type(c) for c in settings.cameras}
    if SyntheticCamera in kinds:
        if len(kinds) > 1:
            raise MomlocError("cameras: synthetic cameras cannot be mixed with real ones")
        from capture.synthetic import SyntheticRig, make_scene

        syn = settings.synthetic
        scene = make_scene(
            syn.preset,
            seed=syn.seed,
            people=syn.people,
            fps=syn.fps,
            detector_profile=syn.detector_profile,
        )
        indices = [c.index for c in settings.cameras]
        available = len(scene.cameras)
        for position, index in enumerate(indices):
            if index >= available:
                raise MomlocError(
                    f"cameras.{position}.index: scene '{syn.preset}' has cameras 0..{available - 1}"
                )
        if syn.detections == "rendered":
            render_every = 1
        elif syn.preview_fps > 0:
            render_every = max(1, round(syn.fps / syn.preview_fps))
        else:
            render_every = 0
        rig = SyntheticRig(scene, indices, fps=syn.fps, render_every=render_every)
        return rig, rig
    from capture.rig import CameraRig
    from capture.worker import CameraWorker

    workers = [CameraWorker(_open_source(c), camera=k) for k, c in enumerate(settings.cameras)]
    return CameraRig(workers), None


def _open_source(camera: Any) -> Any:
    from capture.sources import V4L2Source, VideoFileSource

    if isinstance(camera, V4l2Camera):
        device: int | str = int(camera.device) if camera.device.isdigit() else camera.device
        return V4L2Source(device, width=camera.width, height=camera.height, fps=camera.fps)
    if not camera.path.is_file():
        raise MomlocError(f"cameras: video file {camera.path} does not exist")
    return VideoFileSource(camera.path, fps=camera.fps, loop=camera.loop)


def build_detect_stage(settings: Settings, player: Any) -> Any:
    """The detector stage, or the simulator's boxes when the demo asks for them."""
    if player is not None and settings.synthetic.detections == "simulated":
        from capture.synthetic import SimulatedDetections

        return SimulatedDetections(player)
    from models.detector import create_detector

    options = {
        "model_path": settings.detector.model_path,
        "letterbox": settings.detector.letterbox,
        "input_size": settings.detector.input_size,
    }
    threads = settings.detector.threads
    explicit = settings.detector.model_fields_set
    if settings.detection.schedule == "auto" and "threads" not in explicit:
        threads = 1  # beside the pipeline, one thread leaves a core free (bench/realtime.py)
    detector = create_detector(
        settings.detector.kind,
        score_threshold=settings.detector.score_threshold,
        threads=threads,
        **{key: value for key, value in options.items() if value is not None},
    )
    schedule = None
    if settings.detection.schedule == "auto":
        from service.detection_schedule import DetectionScheduler

        detection = settings.detection
        schedule = DetectionScheduler(
            detector,
            settings.detector.score_threshold,
            max_duty=detection.max_duty,
            cameras_per_call=detection.cameras_per_call,
            nice=detection.nice,
            carrier={"flow": detection.flow, "max_age_s": detection.max_age_s},
            refiner=_window_refiner(detector, detection.windows, detection.window_below_px),
        )
    return DetectorStage(detector, settings.detector.score_threshold, schedule)


def _window_refiner(detector: Any, windows: int, below_px: float) -> WindowRefiner | None:
    """The second look at small people (``detection.windows``), for detectors of any input size."""
    if windows == 0:
        return None
    resized = getattr(detector, "resized", None)
    if resized is None:
        raise MomlocError(
            f"detection.windows: detector {detector.kind!r} has a fixed input size; windows need "
            "one of any size (kind: nanodet)"
        )
    return WindowRefiner(resized((96, 160)), max_height=below_px, max_windows=windows)


def floor_extent(settings: Settings, runtime: Any, player: Any) -> dict[str, float] | None:
    """Map extent: settings, else the synthetic room, else the model's training area."""
    if settings.floor is not None:
        return settings.floor.model_dump()
    if player is not None:
        return player.floor_extent()
    bounds = getattr(runtime, "world_bounds", None)
    if bounds is not None:
        (xmin, ymin), (xmax, ymax) = bounds
        return {"xmin": float(xmin), "xmax": float(xmax), "ymin": float(ymin), "ymax": float(ymax)}
    return None


def build_daemon(settings: Settings, *, require_model: bool = True) -> Daemon:
    """Open cameras, load the detector and model, wire the pipeline (not started yet)."""
    from models.mom_runtime import MomRuntime
    from service.tracking import RECOMMENDED, Tracker

    runtime = None
    try:
        runtime = MomRuntime.load(settings.model_dir)
    except MomlocError:
        if require_model:
            raise
        log.warning("no usable model in %s; serving without positions", settings.model_dir)
    rig, player = build_rig(settings)
    detect = build_detect_stage(settings, player)
    hub = Hub()
    pipeline = Pipeline(
        rig,
        detect,
        hub,
        num_cameras=len(settings.cameras),
        runtime=runtime,
        model_dir=settings.model_dir,
        tracker=Tracker(
            fps_hint=30.0, max_missing_s=settings.tracking.max_missing_s, **RECOMMENDED
        ),
        max_error_px=settings.tracking.max_error_px,
    )
    if runtime is not None and int(runtime.num_cameras) != len(settings.cameras):
        raise MomlocError(
            f"model_dir: {settings.model_dir} expects {runtime.num_cameras} cameras, "
            f"{len(settings.cameras)} are configured"
        )
    extras = {}
    if player is not None:
        extras["source"] = {"synthetic": settings.synthetic.model_dump()}
    daemon = Daemon(
        hub=hub,
        pipeline=pipeline,
        camera_names=[camera_name(c) for c in settings.cameras],
        token=settings.token_value(),
        stream_rate=settings.stream.rate,
        ping_interval=settings.stream.ping_interval,
        ping_timeout=settings.stream.ping_timeout,
        floor=floor_extent(settings, runtime, player),
        extras=extras,
        watcher=ModelWatcher(pipeline) if settings.watch_model else None,
        bind_host=settings.host,
        allowed_hosts=list(settings.allowed_hosts),
        allowed_origins=list(settings.allowed_origins),
        setup=SetupSession(
            settings.data_dir,
            image_sizes=lambda: _known_sizes(pipeline),
            attach=pipeline.add_detection_listener,
            detach=pipeline.remove_detection_listener,
        ),
    )
    from service.outputs import build_outputs

    daemon.outputs = build_outputs(settings, daemon)
    return daemon


def _known_sizes(pipeline: Pipeline) -> list[tuple[int, int]] | None:
    """Every camera's frame size once each has delivered a frame, else None."""
    sizes = list(pipeline.image_sizes)
    return None if any(size is None for size in sizes) else sizes


def bind_socket(host: str, port: int) -> socket.socket:
    """Listen on host:port now, so a taken port is a one-line user error, not a traceback."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(2048)  # connections made right after the banner wait in the backlog
    except OSError as error:
        sock.close()
        raise MomlocError(f"cannot listen on {host}:{port} ({error.strerror})") from None
    sock.set_inheritable(True)
    return sock


def make_server(daemon: Daemon, host: str, port: int) -> Any:
    """A uvicorn server for ``daemon`` (run it with ``server.run(sockets=[sock])``)."""
    import uvicorn

    from service.app import create_app

    config = uvicorn.Config(
        create_app(daemon),
        host=host,
        port=port,
        log_level="warning",
        ws="websockets-sansio",
        ws_ping_interval=daemon.ping_interval,
        ws_ping_timeout=daemon.ping_timeout,
        # snapshots are a few hundred bytes: per-client zlib costs more CPU than it saves
        ws_per_message_deflate=False,
        # SIGTERM must stop the daemon within seconds, whatever a client is doing (a slow body,
        # a long request): open connections get this long, then they are cut
        timeout_graceful_shutdown=GRACEFUL_SHUTDOWN_S,
    )
    return uvicorn.Server(config)


def run_server(daemon: Daemon, host: str, port: int, on_ready: Any = None) -> None:
    """Bind, announce, and serve until interrupted (uvicorn owns signals and the loop)."""
    sock = bind_socket(host, port)
    server = make_server(daemon, host, port)
    if on_ready is not None:
        on_ready(sock.getsockname()[1])
    server.run(sockets=[sock])
    _exit_soon_if_stuck(GRACEFUL_SHUTDOWN_S + 5)


def _exit_soon_if_stuck(seconds: float) -> None:
    """After serving, make sure the process ends: a request still running in a worker thread
    (those threads are not daemons) would otherwise keep it alive after SIGTERM."""

    def deadline() -> None:
        time.sleep(seconds)
        log.warning("momloc: a request was still running %.0f s after stopping; exiting", seconds)
        logging.shutdown()
        os._exit(0)

    threading.Thread(target=deadline, name="momloc-exit-deadline", daemon=True).start()


@dataclass
class BackgroundServer:
    """A daemon served by uvicorn in a thread (tests and benchmarks)."""

    daemon: Daemon
    port: int
    server: Any
    thread: threading.Thread
    sock: socket.socket

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=15)
        self.sock.close()


def serve_in_thread(daemon: Daemon, host: str = "127.0.0.1", port: int = 0) -> BackgroundServer:
    """Start serving ``daemon`` on host:port (0: any free port); returns once it accepts."""
    sock = bind_socket(host, port)
    server = make_server(daemon, host, sock.getsockname()[1])
    thread = threading.Thread(
        target=server.run, kwargs={"sockets": [sock]}, name="uvicorn", daemon=True
    )
    thread.start()
    deadline = time.time() + 60
    while not server.started:
        if time.time() > deadline or not thread.is_alive():
            sock.close()
            raise MomlocError("the HTTP server did not start")
        time.sleep(0.02)
    return BackgroundServer(daemon, sock.getsockname()[1], server, thread, sock)
