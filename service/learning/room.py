"""The learning room as the daemon holds it: the self-label listener and, when turned on, the
background improver and the self-healing job, started and stopped with the pipeline, reported
together in health."""

from __future__ import annotations

from typing import Any

from service.learning.healer import Healer
from service.learning.improve import Improver
from service.learning.listener import SelfLabeler
from service.stages import FrameResult


class LearningRoom:
    """A frame listener (it hands frame sets to :class:`SelfLabeler`) that owns the improver's
    thread: the pipeline closes it when it stops (``service.pipeline.live``)."""

    def __init__(
        self,
        labeler: SelfLabeler,
        improver: Improver | None = None,
        healer: Healer | None = None,
    ) -> None:
        self.labeler, self.improver, self.healer = labeler, improver, healer
        if healer is not None:
            labeler.followers.append(healer)
        self._started = False

    def __call__(self, result: FrameResult) -> None:
        if not self._started and self.improver is not None:
            self._started = True  # with the first frame set: the pipeline is running
            self.improver.start()
        self.labeler(result)

    def close(self) -> None:
        if self.improver is not None:
            self.improver.close()
        self.labeler.close()

    def stats(self) -> dict[str, Any]:
        """``/v1/health`` ``learning``."""
        improvement = {"enabled": False} if self.improver is None else self.improver.status()
        repairs = [] if self.healer is None else self.healer.status()
        return {**self.labeler.stats(), "improvement": improvement, "repairs": repairs}

    def repair_messages(self) -> dict[int, str]:
        """Per camera the newest self-healing message (the map shows it with the alert)."""
        if self.healer is None:
            return {}
        return {r["camera"]: r["message"] for r in self.healer.status()}
