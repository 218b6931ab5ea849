"""What outputs share: the publisher contract and the latest-value slot between threads.

The contract (:class:`Publisher`: ``name``, ``offer``, ``stats``) is defined in
:mod:`service.snapshot`, beside the value it takes, so the pipeline's hub can type its
publishers without importing an output; it is re-exported here for the outputs.

This is deliberately tiny; a general publisher registry (WebSocket hub, MQTT, file writer behind
one ``type`` key) can grow out of it.
"""

from __future__ import annotations

import threading
from typing import Any

from service.snapshot import Publisher

__all__ = ["LatestSlot", "Publisher"]


class LatestSlot:
    """A one-item mailbox between threads: ``put`` overwrites (newest wins), ``take`` empties.

    ``overwritten`` counts values replaced before anyone took them (skipped by a slow reader).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._value: Any = None
        self.overwritten = 0

    def put(self, value: Any) -> None:
        with self._lock:
            if self._value is not None:
                self.overwritten += 1
            self._value = value

    def take(self) -> Any:
        with self._lock:
            value, self._value = self._value, None
            return value

    def peek(self) -> Any:
        with self._lock:
            return self._value
