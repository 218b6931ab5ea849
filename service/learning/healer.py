"""The self-healing job: per flagged camera, collect, repair, check, serve, tell the user.

State per camera (``status()`` in ``/v1/health`` ``learning.repairs``, on the set-up page and as
the camera's ``alignment.repair`` on the map): ``collecting`` from the first frame set after the
camera-moved check raised it (positions the other cameras give, :func:`service.learning.heal.
heal_samples`), ``repaired`` once a repair passed its check and was served (the message then says
when the camera moved, how many positions it re-learned from and the held-out error), or
``failed`` (the check did not pass with ``MAX_POSITIONS``: the user is asked to re-collect the
marks; below that, a failed check drops the samples and collection starts over with twice as
many). A camera whose alert clears by itself (put back where it
was) stops collecting.

Serving a repair: a copy of the model directory in service with the repaired ``model.json``
(the encoder file is unchanged), installed as ``data_dir/model`` with the former kept as
``model.previous``, and hot-loaded (``Pipeline.reload_model``). The new model resets the
camera-moved checks (new baseline, new image references where the camera now looks), which
clears the alert.
"""

from __future__ import annotations

import functools
import logging
import shutil
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.atomic import atomic_write, atomic_write_json, replace_folder
from common.errors import MomlocError
from service.camera_health.reprojection import WHAT_TO_DO
from service.learning.gate import labels_error
from service.learning.heal import HealSamples, Repair, heal_samples, repair
from service.learning.improve import Serving
from service.learning.labels import LabelRules
from service.learning.listener import SelfLabeler
from service.setup.training import model_path
from service.stages import FrameResult

log = logging.getLogger("momloc.learning")
MIN_POSITIONS = 120
MAX_POSITIONS = 1600
HOW = {"transform": "its image turned", "refit": "its floor map refitted"}
SINGLE_VIEW_FALLBACK_M = 0.3  # a camera with no self-labels before the bump: a typical lone view


@dataclass
class Session:
    camera: int
    since: float  # capture time of the first frame set with the camera flagged
    wall: float  # wall-clock time of the same moment (for the message)
    need: int
    samples: HealSamples = field(default_factory=HealSamples.empty)
    last: dict[int, float] = field(default_factory=dict)
    state: str = "collecting"
    result: Repair | None = None
    message: str | None = None


class Healer:
    """Called by the self-label worker with every frame set and the flagged cameras."""

    def __init__(
        self,
        data_dir: Path,
        labeler: SelfLabeler,
        serving: Serving,
        *,
        rules: LabelRules | None = None,
        min_positions: int = MIN_POSITIONS,
    ) -> None:
        self.data_dir = Path(data_dir)
        self.labeler, self.serving = labeler, serving
        self.rules = rules or LabelRules(min_interval_s=0.2)
        self.min_positions = min_positions
        self.sessions: dict[int, Session] = {}
        self.done: list[Session] = []
        self._lock = threading.Lock()

    def __call__(self, result: FrameResult, moved: set[int]) -> None:
        runtime = result.runtime
        if runtime is None or int(runtime.num_cameras) < 2:
            return
        with self._lock:
            for camera in moved - set(self.sessions):
                now = time.time()
                self.sessions[camera] = Session(camera, result.t_capture, now, self.min_positions)
            for camera in set(self.sessions) - moved:
                del self.sessions[camera]  # put back, or repaired (the checks were reset)
            active = [s for s in self.sessions.values() if s.state == "collecting"]
        for session in active:
            heal_samples(result, session.camera, self.rules, session.last, session.samples)
            if session.samples.n >= session.need:
                self._repair(session)

    def _repair(self, session: Session) -> None:
        runtime = self.serving.runtime
        if runtime is None:
            return
        meta, model_dir = runtime.meta, runtime.model_dir
        try:
            fixed = repair(meta, session.camera, session.samples, self._single_view(session))
        except MomlocError as error:
            self._retry(session, f"repair failed: {error}")
            return
        session.result = fixed
        if not fixed.passed:
            self._retry(
                session,
                f"re-learned error {fixed.error_m:.2f} m is over what the repair can reach "
                f"({fixed.reachable_m:.2f} m)",
            )
            return
        moved_at = time.strftime("%H:%M", time.localtime(session.wall))
        session.message = (
            f"camera {session.camera} moved at {moved_at}; re-learned from {fixed.positions} "
            f"positions ({HOW[fixed.how]}); error {fixed.error_m:.2f} m "
            f"(reachable {fixed.reachable_m:.2f} m)"
        )
        fixed.meta["learning"] = {  # its own room: the labels of the former one saw m elsewhere
            "repaired": {
                "camera": session.camera,
                "positions": fixed.positions,
                "error_m": fixed.error_m,
                "reachable_m": fixed.reachable_m,
                "time": time.time(),
            }
        }
        try:
            self._serve(Path(model_dir), fixed)
        except (MomlocError, OSError) as error:
            self._retry(session, f"repaired model not served: {error}")
            return
        session.state = "repaired"
        with self._lock:
            self.done = [*self.done[-4:], session]
        log.info("self-healing: %s", session.message)

    def _retry(self, session: Session, why: str) -> None:
        log.warning("self-healing camera %d: %s", session.camera, why)
        session.message = f"camera {session.camera}: {why}; collecting more positions"
        session.samples = HealSamples.empty()
        session.need *= 2
        if session.need > MAX_POSITIONS:
            session.state = "failed"
            session.message = f"camera {session.camera}: {why}; {WHAT_TO_DO}"

    def _single_view(self, session: Session) -> float:
        """The camera's single-view error against the self-labels from before the bump."""
        store = self.labeler.store
        labels = None if store is None else store.load()
        runtime = self.serving.runtime
        if labels is None or runtime is None:
            return SINGLE_VIEW_FALLBACK_M
        before = labels.subset(labels.t < session.since)
        if before.n == 0:
            return SINGLE_VIEW_FALLBACK_M
        error = labels_error(runtime, before, cameras=[session.camera])
        return SINGLE_VIEW_FALLBACK_M if error is None else error

    def _serve(self, current: Path, fixed: Repair) -> None:
        final = model_path(self.data_dir)
        staging = final.with_name(final.name + ".repair")
        shutil.rmtree(staging, ignore_errors=True)
        for path in current.iterdir():
            if path.is_file() and path.name != "model.json":
                atomic_write(staging / path.name, functools.partial(_copy, path))
        atomic_write_json(staging / "model.json", fixed.meta)
        replace_folder(staging, final, ".previous")
        self.serving.reload_model(final)

    def status(self) -> list[dict[str, Any]]:
        with self._lock:
            waiting = [s for s in self.sessions.values() if s.state != "repaired"]
            sessions = [*self.done, *waiting]  # a repaired one until its alert clears: once
        out = []
        for s in sessions:
            out.append(
                {
                    "camera": s.camera,
                    "state": s.state,
                    "positions": s.samples.n,
                    "needed": s.need,
                    "error_m": None if s.result is None else s.result.error_m,
                    "reachable_m": None if s.result is None else s.result.reachable_m,
                    "message": s.message
                    or f"camera {s.camera} moved: re-learning from people walking "
                    f"({s.samples.n} of {s.need} positions)",
                }
            )
        return out


def _copy(source: Path, target: Path) -> None:
    shutil.copyfile(source, target)
