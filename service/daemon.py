"""The composition root: builds the daemon from settings (cameras, detector, MoM model,
pipeline and its listeners, hub, outputs); ``service.server`` serves it.

``momloc serve`` and ``momloc demo`` differ only in the settings they pass here, so the demo
exercises exactly the code users run on real cameras.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from models.detector.windows import WindowRefiner
from models.errors import MomlocError
from service.detector_stage import DetectorStage
from service.hub import Hub
from service.model_watch import ModelWatcher
from service.pipeline import Pipeline
from service.settings import FileCamera, Settings, SyntheticCamera, V4l2Camera
from service.setup.session import SetupSession
from service.setup.training import TrainingJob, model_path
from service.setup.verify import Verifier
from service.state import NO_MODEL, Daemon
from service.tracking import RECOMMENDED, Tracker

log = logging.getLogger("momloc")


def camera_name(camera: Any) -> str:
    if camera.name:
        return camera.name
    if isinstance(camera, V4l2Camera):
        return camera.device
    if isinstance(camera, FileCamera):
        return camera.path.name if camera.camera is None else f"{camera.path.name}/{camera.camera}"
    return f"synthetic-{camera.index}"


def build_rig(settings: Settings) -> tuple[Any, Any]:
    """The camera rig for ``settings.cameras`` and, for synthetic cameras, the scene it shows."""
    kinds = {type(c) for c in settings.cameras}
    if SyntheticCamera in kinds:
        if len(kinds) > 1:
            raise MomlocError("cameras: synthetic cameras cannot be mixed with real ones")
        from capture.synthetic import SyntheticRig
        from service.simulated_detections import scene_for

        syn = settings.synthetic
        scene = scene_for(syn)
        indices = [c.index for c in settings.cameras if isinstance(c, SyntheticCamera)]
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
        return rig, scene
    from capture.rig import CameraRig
    from capture.worker import CameraWorker

    workers = [CameraWorker(_open_source(c), camera=k) for k, c in enumerate(settings.cameras)]
    return CameraRig(workers, max_skew=settings.tracking.max_skew_s), None


def _open_source(camera: Any) -> Any:
    from capture.replay import open_file_source
    from capture.sources import V4L2Source

    if isinstance(camera, V4l2Camera):
        device: int | str = int(camera.device) if camera.device.isdigit() else camera.device
        return V4L2Source(device, width=camera.width, height=camera.height, fps=camera.fps)
    return open_file_source(camera.path, camera=camera.camera, fps=camera.fps, loop=camera.loop)


def build_detect_stage(settings: Settings, player: Any) -> Any:
    """The detector stage, or the simulator's boxes when the demo asks for them."""
    if player is not None and settings.synthetic.detections == "simulated":
        from service.simulated_detections import SimulatedDetections

        indices = [c.index for c in settings.cameras if isinstance(c, SyntheticCamera)]
        return SimulatedDetections(player, indices)  # a player: build_rig saw only synthetic
    from models.detector import create_detector

    options = {
        "model_path": settings.detector.model_path,
        "letterbox": settings.detector.letterbox,
        "input_size": settings.detector.input_size,
        "max_shrink": settings.detector.max_shrink,
    }
    threads = settings.detector.threads
    explicit = settings.detector.model_fields_set
    if settings.detection.schedule == "auto" and "threads" not in explicit:
        threads = 1  # beside the pipeline, one thread leaves a core free (bench/realtime.py)
    detector = create_detector(
        settings.detector.kind,
        score_threshold=settings.detector.score_threshold,
        threads=threads,
        keypoints=settings.detector.keypoints,
        **{key: value for key, value in options.items() if value is not None},
    )
    schedule = None
    if settings.detection.schedule == "auto":
        from service.detection_schedule import DetectionScheduler

        detection = settings.detection
        schedule = DetectionScheduler(
            detector,
            max_duty=detection.max_duty,
            cameras_per_call=detection.cameras_per_call,
            nice=detection.nice,
            carrier={"flow": detection.flow, "max_age_s": detection.max_age_s},
            refiner=_window_refiner(detector, detection.windows, detection.window_below_px),
        )
    return DetectorStage(detector, schedule)


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
    bounds = getattr(runtime, "world_bounds", None)  # None: a model from before it was stored
    if bounds is not None:
        (xmin, ymin), (xmax, ymax) = bounds
        if xmax > xmin and ymax > ymin:  # marks on one line span no area to draw
            return {"xmin": xmin, "xmax": xmax, "ymin": ymin, "ymax": ymax}
    return None


def resolve_model_dir(settings: Settings) -> Path | None:
    """The model to serve: ``model_dir``, else the one the /setup page trained, else None
    (set-up mode). Never the shipped demo model: on real cameras its positions mean nothing."""
    if settings.model_dir is not None:
        return settings.model_dir
    trained = model_path(settings.data_dir)
    return trained if (trained / "model.json").is_file() else None


def build_tracker(settings: Settings) -> Tracker:
    """The tracker live and offline (``momloc track``) alike: the recommended settings
    (``service.tracking.RECOMMENDED``, measured in ``bench/stream_accuracy.py``)."""
    return Tracker(fps_hint=30.0, max_missing_s=settings.tracking.max_missing_s, **RECOMMENDED)


def build_daemon(settings: Settings, *, require_model: bool = True) -> Daemon:
    """Open cameras, load the detector and model, wire the pipeline (not started yet)."""
    from models.mom_runtime import MomRuntime

    runtime = None
    model_dir = resolve_model_dir(settings)
    if model_dir is None:
        log.warning("%s (set-up mode: no positions until a model is trained)", NO_MODEL)
    else:
        try:
            runtime = MomRuntime.load(model_dir)
        except MomlocError:
            if require_model:
                raise
            log.warning("no usable model in %s; serving without positions", model_dir)
    rig, player = build_rig(settings)
    detect = build_detect_stage(settings, player)
    hub = Hub()
    pipeline = Pipeline(
        rig,
        detect,
        hub,
        num_cameras=len(settings.cameras),
        runtime=runtime,
        model_dir=model_dir,
        tracker=build_tracker(settings),
        max_error_px=settings.tracking.max_error_px,
        outside_area=settings.tracking.outside_area,
    )
    extras = {}
    if player is not None:
        extras["source"] = {"synthetic": settings.synthetic.model_dump()}
    session = SetupSession(
        settings.data_dir,
        image_sizes=lambda: _known_sizes(pipeline),
        attach=pipeline.add_detection_listener,
        detach=pipeline.remove_detection_listener,
    )  # its state machine (record / train / verify, one at a time) is given to the other two
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
        setup=session,
    )
    daemon.training = TrainingJob(lambda: session.data_dir, pipeline.reload_model, session.steps)
    verifier = Verifier(
        hub.latest,
        lambda: pipeline.model_dir if pipeline.runtime else None,
        settings.data_dir,
        session.steps,
    )
    daemon.verifier = verifier
    if player is not None:  # synthetic.follow_setup: the simulated person obeys /setup
        from models.simulate.following import FollowingWalker

        walker = getattr(player, "walkers", None)
        if isinstance(walker, FollowingWalker):
            walker.target = lambda: session.target() or verifier.target()
    from service.outputs import build_outputs

    daemon.outputs = build_outputs(settings, daemon)
    return daemon


def _known_sizes(pipeline: Pipeline) -> list[tuple[int, int]] | None:
    """Every camera's frame size once each has delivered a frame, else None."""
    known = [size for size in pipeline.image_sizes if size is not None]
    return known if len(known) == len(pipeline.image_sizes) else None
