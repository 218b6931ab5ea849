"""The learning room as the daemon holds it: the self-label listener and, when turned on, the
background improver, started and stopped with the pipeline, reported together in health."""

from __future__ import annotations

from typing import Any

from service.learning.improve import Improver
from service.learning.listener import SelfLabeler
from service.stages import FrameResult


class LearningRoom:
    """A frame listener (it hands frame sets to :class:`SelfLabeler`) that owns the improver's
    thread: the pipeline closes it when it stops (``service.pipeline.live``)."""

    def __init__(self, labeler: SelfLabeler, improver: Improver | None = None) -> None:
        self.labeler, self.improver = labeler, improver
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
        return {**self.labeler.stats(), "improvement": improvement}
