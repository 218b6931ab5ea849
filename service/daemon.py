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
from service.learning.healer import Healer
from service.learning.improve import ImproveOptions, Improver
from service.learning.labels import LabelRules
from service.learning.listener import SelfLabeler
from service.learning.room import LearningRoom
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
    if settings.learning.enabled:
        daemon.learning = build_learning(settings, pipeline, daemon.training)
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


def build_learning(
    settings: Settings, pipeline: Pipeline, training: TrainingJob | None = None
) -> LearningRoom:
    """The self-label collector, the background improver and the self-healing job
    (``service.learning``), hung off the pipeline."""
    learning = settings.learning
    labeler = SelfLabeler(
        settings.data_dir,
        rules=LabelRules(
            min_views=learning.min_views,
            max_std_m=learning.max_std_m,
            max_cost=learning.max_cost,
            min_separation_m=learning.min_separation_m,
            min_interval_s=learning.min_interval_s,
        ),
        moved=lambda: {c.camera for c in pipeline.alignment_status() if c.moved},
        max_bytes=int(learning.max_mb * 1e6),
    )
    improver = None
    if learning.improve:
        options = ImproveOptions(
            every_labels=learning.improve_every_labels,
            nice_by=learning.improve_nice,
            time_budget_s=learning.improve_time_budget_s,
            epochs=learning.improve_epochs,
        )
        improver = Improver(
            settings.data_dir,
            labeler,
            pipeline,
            marks=learning.marks,
            options=options,
            paused=lambda: (
                any(c.moved for c in pipeline.alignment_status())
                or (training is not None and training.status()["state"] == "running")
            ),
        )
    healer = None
    if learning.heal:
        healer = Healer(
            settings.data_dir, labeler, pipeline, min_positions=learning.heal_min_positions
        )
    room = LearningRoom(labeler, improver, healer)
    pipeline.add_listener(room)
    return room


def _known_sizes(pipeline: Pipeline) -> list[tuple[int, int]] | None:
    """Every camera's frame size once each has delivered a frame, else None."""
    known = [size for size in pipeline.image_sizes if size is not None]
    return known if len(known) == len(pipeline.image_sizes) else None
