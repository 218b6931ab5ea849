"""Verification: "stand on mark B2", then the live error there, for a few marks.

After training, the user stands on some marks (the recording's, or new ones typed now and never
used in training, the honest test) and the page shows how far the served position is from each
mark, live, and a summary ("median 0.09 m over 4 marks"). The summary is kept with the model it
describes, in its ``model.json`` when the daemon trained it, else in ``data_dir`` (never in a
shipped or foreign file: :mod:`service.setup.check_store`), and shown in ``/v1/health``.

How a mark is measured: after the move and countdown, the published snapshots of ``seconds`` are
read (the hub's newest, polled at 10 Hz: the verifier must never slow the pipeline) and scored by
:mod:`service.setup.check_score` (nearest served person, median per mark, median over marks),
the statistic ``momloc eval --served`` computes offline on a recording of the same marks.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common.errors import MomlocError
from service.setup.check_score import mark_error, nearest_error, summarise
from service.setup.check_store import store_check, stored_check
from service.setup.marks import FloorMark
from service.setup.steps import SetupSteps
from service.snapshot import Snapshot

POLL_S = 0.1


class Cancelled(Exception):
    """The user stopped the check."""


class Verifier:
    """At most one check at a time, on the daemon's published positions."""

    def __init__(
        self,
        latest: Callable[[], Snapshot],
        model_dir: Callable[[], Path | None],
        data_dir: Path,
        steps: SetupSteps | None = None,
    ) -> None:
        self._latest = latest  # the hub's newest snapshot
        self._model_dir = model_dir  # the model being served (None: no model)
        self.data_dir = Path(data_dir)  # where results of models not the daemon's own go
        self.steps = SetupSteps() if steps is None else steps  # shared with record and train
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._state: dict[str, Any] = {"state": "idle"}

    def start(
        self, marks: list[FloorMark], seconds: float, move_s: float, countdown_s: float
    ) -> dict[str, Any]:
        """Start the check; holds the set-up's ``verify`` step until it has ended."""
        self.steps.begin("verify")
        try:
            return self._launch(marks, seconds, move_s, countdown_s)
        except BaseException:
            self.steps.end("verify")
            raise

    def _launch(
        self, marks: list[FloorMark], seconds: float, move_s: float, countdown_s: float
    ) -> dict[str, Any]:
        with self._lock:
            if self._model_dir() is None:
                raise MomlocError("no model yet: record floor marks and train first")
            if not marks:
                raise MomlocError("marks: give at least one mark (or record marks first)")
            self._stop.clear()
            self._state = {
                "state": "running",
                "marks": [
                    {"name": m.name, "x": m.x, "y": m.y, "error_m": None, "samples": 0}
                    for m in marks
                ],
                "summary": None,
            }
            self._thread = threading.Thread(
                target=self._run,
                args=(marks, seconds, move_s, countdown_s),
                name="momloc-verify",
                daemon=True,
            )
            self._thread.start()
        return self.status()

    def _run(
        self, marks: list[FloorMark], seconds: float, move_s: float, countdown_s: float
    ) -> None:
        try:
            for i, mark in enumerate(marks):
                self._state.update(mark=mark.name, target=[mark.x, mark.y], live_error_m=None)
                self._wait(f"stand on mark {mark.name}", "move", move_s + countdown_s)
                errors = self._measure(mark, seconds)
                entry = self._state["marks"][i]
                entry["samples"] = len(errors)
                entry["error_m"] = mark_error(errors)
            summary = summarise(self._state["marks"])
            self._state["summary"] = summary
            self._state["stored_in"] = self._store(summary)
            self._state.update(state="done", instruction=summary["text"], mark=None, target=None)
        except Cancelled:
            self._state.update(state="stopped", instruction="check stopped", target=None)
        except (MomlocError, OSError) as error:
            self._state.update(state="failed", error=str(error), target=None)
        finally:
            self.steps.end("verify")  # the status is final: the next step may start

    def _wait(self, instruction: str, kind: str, seconds: float) -> None:
        end = time.monotonic() + seconds
        self._state.update(instruction=instruction, kind=kind)
        while (left := end - time.monotonic()) > 0:
            self._state["remaining_s"] = round(left, 1)
            if self._stop.wait(min(POLL_S, left)):
                raise Cancelled

    def _measure(self, mark: FloorMark, seconds: float) -> list[float]:
        self._state.update(instruction=f"stay on {mark.name}: measuring", kind="measure")
        end, seen, errors = time.monotonic() + seconds, None, []
        while (left := end - time.monotonic()) > 0:
            self._state["remaining_s"] = round(left, 1)
            snapshot = self._latest()
            if snapshot.seq != seen and (
                (error := nearest_error(snapshot.people, mark.x, mark.y)) is not None
            ):
                seen = snapshot.seq
                errors.append(error)
                self._state["live_error_m"] = round(error, 3)
            if self._stop.wait(min(POLL_S, left)):
                raise Cancelled
        return errors

    def _store(self, summary: dict[str, Any]) -> str | None:
        """Keep the summary for the served model (:mod:`service.setup.check_store`)."""
        model_dir = self._model_dir()
        if model_dir is None:
            return None
        return str(store_check(summary, Path(model_dir), self.data_dir))

    def stored(self) -> dict[str, Any] | None:
        """The summary kept for the served model, if it was ever checked."""
        return stored_check(self._model_dir(), self.data_dir)

    def stop(self) -> dict[str, Any]:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        return self.status()

    def target(self) -> tuple[float, float] | None:
        """The mark the check sends the person to now (the synthetic follower goes there)."""
        target = self._state.get("target") if self._state.get("state") == "running" else None
        return None if target is None else (float(target[0]), float(target[1]))

    def status(self) -> dict[str, Any]:
        return json.loads(json.dumps(self._state))  # a deep copy: the thread keeps writing
