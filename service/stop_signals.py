"""Ctrl-C and SIGTERM stop every ``momloc`` command cleanly, however it was started.

Why explicit handlers: Python turns SIGINT into ``KeyboardInterrupt`` only when SIGINT was not
ignored as the interpreter started. A command started with ``&`` from a non-interactive shell (and
by some CI runners and supervisors) inherits SIGINT ignored, so Ctrl-C or ``kill -INT`` did
nothing: ``momloc record`` kept recording. SIGTERM, what ``kill``, ``docker stop`` and supervisors
send, ends Python at once by default: no ``finally`` runs, so ``record`` left no
``manifest.json`` and ``momloc track`` refused the folder.

How: the CLI runs every command inside :func:`handle_stop_signals`, one handler for both signals
that raises :class:`Stopped` (a ``KeyboardInterrupt``) in the main thread. Each command's own
clean-up then runs as it does for Ctrl-C at a terminal: ``record`` closes its videos and writes
the manifest, ``collect`` flushes the rows it kept, ``train`` and ``track`` write atomically and
so leave the former output or none, never half a file; ``serve``/``demo`` shut the server and the
pipeline down (uvicorn installs its own handlers while it serves, hands these back when it stops,
and re-raises the signal to them). The CLI prints one line and exits 128 + the signal number,
except where a signal is the command's normal end (an open-ended recording, a daemon): 0.

Only the first signal raises. One arriving while the command cleans up is ignored: an impatient
second Ctrl-C must not cut the manifest write short (SIGKILL remains for a stuck process); and
:func:`deferred` holds a first signal back across a write that must finish.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Stopped(KeyboardInterrupt):
    """A stop signal arrived (``signum``): unwinds like Ctrl-C, so every clean-up runs."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _State:
    """The handler's memory, main thread only (Python runs signal handlers there)."""

    stopping = False  # a signal was seen: later ones are ignored
    deferring = 0  # depth of open deferred() blocks
    pending: int | None = None  # a signal held back by deferred()


_state = _State()


def _on_signal(signum: int, frame: FrameType | None) -> None:
    if _state.stopping:
        return
    _state.stopping = True
    if _state.deferring:
        _state.pending = signum
        return
    raise Stopped(signum)


@contextmanager
def handle_stop_signals() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise :class:`Stopped` (see the module docstring).

    Outside the main thread (a command run by a test's worker thread) signals cannot be handled
    and the block changes nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _state.stopping, _state.deferring, _state.pending = False, 0, None
    previous = {sig: signal.signal(sig, _on_signal) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextmanager
def deferred() -> Iterator[None]:
    """Hold a stop signal back until the block has finished, then raise it (a file that must be
    completed, such as a recording's manifest)."""
    _state.deferring += 1
    try:
        yield
    finally:
        _state.deferring -= 1
        if not _state.deferring and _state.pending is not None:
            signum, _state.pending = _state.pending, None
            raise Stopped(signum)
