"""The composition root: builds the daemon from settings (cameras, detector, MoM model,
pipeline and its listeners, hub, outputs); ``service.api.server`` serves it.

``momloc serve`` and ``momloc demo`` differ only in the settings they pass here, so the demo
exercises exactly the code users run on real cameras.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from common.errors import MomlocError
from service.api.state import NO_MODEL, Daemon
from service.pipeline.build import build_detect_stage, build_rig, build_tracker, camera_name
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.pipeline.model_watch import ModelWatcher
from service.settings import POSITIONS_ONLY, Settings
from service.setup.session import SetupSession
from service.setup.training import TrainingJob, model_path
from service.setup.verify import Verifier
from service.stages import LocalizationModel

if TYPE_CHECKING:  # built only for the demo's synthetic cameras (service.pipeline.build)
    from models.simulate.scene import Scene

log = logging.getLogger("momloc")


def floor_extent(
    settings: Settings, runtime: LocalizationModel | None, player: Scene | None
) -> dict[str, float] | None:
    """Map extent: settings, else the synthetic room, else the model's training area."""
    if settings.floor is not None:
        return settings.floor.model_dump()
    if player is not None:
        return player.floor_extent()
    bounds = None if runtime is None else runtime.world_bounds  # None: a model from before
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


def build_daemon(settings: Settings, *, require_model: bool = True) -> Daemon:
    """Open cameras, load the detector and model, wire the pipeline (not started yet)."""
    from models.mom.runtime import MomRuntime

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
        preview_images=settings.privacy != POSITIONS_ONLY,
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
        privacy=settings.privacy,
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

        walker = player.walkers
        if isinstance(walker, FollowingWalker):
            walker.target = lambda: session.target() or verifier.target()
    from service.outputs.wiring import build_outputs

    daemon.outputs = build_outputs(settings, daemon)
    return daemon


def _known_sizes(pipeline: Pipeline) -> list[tuple[int, int]] | None:
    """Every camera's frame size once each has delivered a frame, else None."""
    known = [size for size in pipeline.image_sizes if size is not None]
    return known if len(known) == len(pipeline.image_sizes) else None
