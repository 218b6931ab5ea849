"""One set-up step at a time: record, train and check share one small state machine.

Why: the three steps act on the same two things, the recording and the served model, and each
assumes the other two leave them alone. Run side by side they did not (issue 25): a collection
started while training appended rows to the file the trainer was reading (the first model saw
185 rows, the final 258); a check started during a collection scored positions of a person who
was walking to marks and stored "nobody was seen" in ``model.json``; a check during training
measures a model that is swapped under it. So every pair conflicts, and the states are simply::

    idle --record--> recording --(done, stopped, failed)--> idle
    idle --train---> training  --(done, cancelled, failed)--> idle
    idle --verify--> checking  --(done, stopped, failed)--> idle

A step is claimed (:meth:`SetupSteps.begin`) before anything is started and released by the
step's own thread when it has ended and its status is final; a claim that fails to start is
released by the caller. A refused step raises :class:`SetupConflict` naming the step that runs
and how to end it, which the routes answer with 409.
"""

from __future__ import annotations

import threading
from typing import Literal

from common.errors import MomlocError

Step = Literal["record", "train", "verify"]

_RUNNING = {
    "record": "a collection is already running; stop it first",
    "train": "training is already running; cancel it first",
    "verify": "a check is already running; stop it first",
}
_WHAT = {"record": "a collection", "train": "training", "verify": "a check"}
_END = {
    "record": "wait for it or stop it (POST /v1/setup/stop)",
    "train": "wait for it or cancel it (POST /v1/setup/train/cancel)",
    "verify": "wait for it or stop it (POST /v1/setup/verify/stop)",
}


class SetupConflict(MomlocError):
    """The request conflicts with the set-up's state (answered 409)."""


class SetupSteps:
    """Which set-up step runs now (at most one)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._active: Step | None = None

    @property
    def active(self) -> Step | None:
        return self._active

    def begin(self, step: Step) -> None:
        """Claim the set-up for ``step``; :class:`SetupConflict` when a step runs."""
        with self._lock:
            active = self._active
            if active == step:
                raise SetupConflict(_RUNNING[step])
            if active is not None:
                raise SetupConflict(
                    f"{_WHAT[step]} cannot start while {_WHAT[active]} runs; {_END[active]}"
                )
            self._active = step

    def end(self, step: Step) -> None:
        """Release the claim of ``step`` (no-op when another step holds it)."""
        with self._lock:
            if self._active == step:
                self._active = None
