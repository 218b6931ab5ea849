"""A failure that repeats on every frame set is logged once, then counted.

Why: the pipeline thread keeps serving when a frame set fails (the error shows in
``/v1/health``), so a fault that hits every frame set (a broken model, a camera delivering
something unexpected) used to write one traceback per frame, 95 in 10 s, burying everything else
in the log. Now the first failure of a run of failures is logged with its traceback, then one line
every ``every_s`` counts the frame sets that failed since the run began, and the first frame set
that goes through again ends the run with a line saying how many failed in all. A later run
starts over with its own traceback.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from common.errors import shorten

REPORT_EVERY_S = 60.0


class FailureLog:
    """What the log says about repeated failures of one kind of work (``what``, plural)."""

    def __init__(
        self,
        log: logging.Logger,
        what: str,
        every_s: float = REPORT_EVERY_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.log, self.what, self.every_s, self.clock = log, what, every_s, clock
        self.failed_in_run = 0  # frame sets failed since the run began (0: no run)
        self._began = self._reported = 0.0
        self._began_wall = ""

    def failed(self, error: BaseException) -> None:
        """Count a failure; the first of a run is logged with its traceback."""
        now = self.clock()
        self.failed_in_run += 1
        if self.failed_in_run == 1:
            self._began = self._reported = now
            self._began_wall = time.strftime("%H:%M:%S")
            self.log.error(
                "%s fail: %s (logged once; then a count every %g s)",
                self.what,
                type(error).__name__,
                self.every_s,
                exc_info=error,
            )
        elif now - self._reported >= self.every_s:
            self._reported = now
            self.log.warning(
                "%d %s failed since %s (%.0f s), the last with %s",
                self.failed_in_run,
                self.what,
                self._began_wall,
                now - self._began,
                shorten(f"{type(error).__name__}: {error}", 300),
            )

    def succeeded(self) -> None:
        """One went through: a run of failures, if any, ends here."""
        if self.failed_in_run:
            self.log.warning(
                "%s work again after %d failed since %s",
                self.what,
                self.failed_in_run,
                self._began_wall,
            )
            self.failed_in_run = 0
