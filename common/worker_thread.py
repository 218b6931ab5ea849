"""One background thread with a stop flag: what every loop of the daemon runs in (the pipeline,
the synthetic rig, the model watcher, the publishers' senders).

The target loops until ``stopping`` is set and waits on that same Event instead of sleeping, so
:meth:`WorkerThread.stop` ends it at once. The thread is a daemon thread: a loop that does not
end within the join timeout never keeps the process alive. ``start`` after ``stop`` starts a new
thread (the API's lifespan restarts the pipeline in tests).
"""

from __future__ import annotations

import threading
from collections.abc import Callable


class WorkerThread:
    """``target`` in a named daemon thread from :meth:`start` until :meth:`stop`."""

    def __init__(self, target: Callable[[], None], name: str, join_s: float = 5.0) -> None:
        self.target, self.name, self.join_s = target, name, join_s
        self.stopping = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self.stopping.clear()
        self._thread = threading.Thread(target=self.target, name=self.name, daemon=True)
        self._thread.start()

    def stop(self, timeout: float | None = None) -> None:
        """Set ``stopping`` and wait up to ``timeout`` (default ``join_s``) for the loop to end."""
        self.stopping.set()
        if self._thread is not None:
            self._thread.join(timeout=self.join_s if timeout is None else timeout)

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()
