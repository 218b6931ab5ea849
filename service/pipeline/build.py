"""The chain's parts built from settings: the camera rig, the detection stage, the tracker.

Shared by the live daemon (``service.daemon``), offline ``momloc track``
(``service.offline.track``), recording (``service.offline.record``) and guided collection
(``service.setup.feeds``), so every path builds its parts the one way. The daemon's own wiring
(model, hub, listeners, API state) stays in the composition root.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from common.errors import MomlocError
from models.detector.base import PersonDetector, Resizable
from models.detector.windows import WindowRefiner
from service.detection.schedule import DetectionScheduler
from service.pipeline.live import Rig
from service.settings import FileCamera, Settings, SyntheticCamera, V4l2Camera
from service.stages import DetectStage
from service.tracking.tracker import RECOMMENDED, Tracker

if TYPE_CHECKING:  # imported inside the functions that open them, as capture and the simulator are
    from capture.sources import FrameSource
    from models.simulate.scene import Scene


def camera_name(camera: V4l2Camera | FileCamera | SyntheticCamera) -> str:
    if camera.name:
        return camera.name
    if isinstance(camera, V4l2Camera):
        return camera.device
    if isinstance(camera, FileCamera):
        return camera.path.name if camera.camera is None else f"{camera.path.name}/{camera.camera}"
    return f"synthetic-{camera.index}"


def build_rig(settings: Settings) -> tuple[Rig, Scene | None]:
    """The camera rig for ``settings.cameras`` and, for synthetic cameras, the scene it shows."""
    kinds = {type(c) for c in settings.cameras}
    if SyntheticCamera in kinds:
        if len(kinds) > 1:
            raise MomlocError("cameras: synthetic cameras cannot be mixed with real ones")
        from capture.synthetic import SyntheticRig
        from service.detection.simulated import scene_for

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

    workers = [
        CameraWorker(_open_source(c), camera=k)
        for k, c in enumerate(settings.cameras)
        if not isinstance(c, SyntheticCamera)  # all of them: synthetic ones were handled above
    ]
    return CameraRig(workers, max_skew=settings.tracking.max_skew_s), None


def _open_source(camera: V4l2Camera | FileCamera) -> FrameSource:
    from capture.replay import open_file_source
    from capture.sources import V4L2Source

    if isinstance(camera, V4l2Camera):
        device: int | str = int(camera.device) if camera.device.isdigit() else camera.device
        return V4L2Source(device, width=camera.width, height=camera.height, fps=camera.fps)
    return open_file_source(camera.path, camera=camera.camera, fps=camera.fps, loop=camera.loop)


def build_detect_stage(settings: Settings, player: Scene | None) -> DetectStage:
    """The detector stage, or the simulator's boxes when the demo asks for them."""
    if player is not None and settings.synthetic.detections == "simulated":
        from service.detection.simulated import SimulatedDetections

        indices = [c.index for c in settings.cameras if isinstance(c, SyntheticCamera)]
        return SimulatedDetections(player, indices)  # a player: build_rig saw only synthetic
    from models.detector.base import detector_from_settings

    threads = settings.detector.threads
    if (
        settings.detection.schedule == "auto"
        and "threads" not in settings.detector.model_fields_set
    ):
        threads = (
            1  # beside the pipeline, one thread leaves a core free (bench/serving/realtime.py)
        )
    detector = detector_from_settings(settings.detector, threads)
    detection = settings.detection
    return DetectionScheduler(
        detector,
        mode=detection.schedule,
        max_duty=detection.max_duty,
        cameras_per_call=detection.cameras_per_call,
        nice=detection.nice,
        carrier={"flow": detection.flow, "max_age_s": detection.max_age_s},
        # every_frame is the plain detector on every frame set (offline runs): no second look
        refiner=None
        if detection.schedule == "every_frame"
        else _window_refiner(detector, detection.windows, detection.window_below_px),
    )


def _window_refiner(
    detector: PersonDetector, windows: int, below_px: float
) -> WindowRefiner | None:
    """The second look at small people (``detection.windows``), for detectors of any input size
    (checked here, once, when the detector is built)."""
    if windows == 0:
        return None
    if not isinstance(detector, Resizable):
        raise MomlocError(
            f"detection.windows: detector {detector.kind!r} has a fixed input size; windows need "
            "one of any size (kind: nanodet)"
        )
    return WindowRefiner(detector.resized((96, 160)), max_height=below_px, max_windows=windows)


def build_tracker(settings: Settings) -> Tracker:
    """The tracker live and offline (``momloc track``) alike: the recommended settings
    (``service.tracking.tracker.RECOMMENDED``, measured in ``bench/serving/stream_accuracy.py``)."""
    return Tracker(fps_hint=30.0, max_missing_s=settings.tracking.max_missing_s, **RECOMMENDED)
