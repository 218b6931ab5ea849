"""``service.stop_signals`` in-process: what the first, a later and a deferred signal do.

The commands themselves are stopped by real signals in ``tests/e2e/test_stop_signals.py``; this
checks the two rules that a subprocess cannot time reliably: only the first signal raises, and
one arriving inside :func:`deferred` waits for the block's end.
"""

from __future__ import annotations

import signal

import pytest

from service.stop_signals import Stopped, deferred, handle_stop_signals


def test_the_first_signal_stops_later_ones_do_not_interrupt_the_clean_up() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with handle_stop_signals():
        with pytest.raises(Stopped) as stopped:
            signal.raise_signal(signal.SIGTERM)
        assert stopped.value.signum == signal.SIGTERM
        assert isinstance(stopped.value, KeyboardInterrupt)  # every `except KeyboardInterrupt`
        signal.raise_signal(signal.SIGINT)  # an impatient second Ctrl-C while cleaning up
    assert signal.getsignal(signal.SIGTERM) is before  # handed back


def test_a_signal_inside_deferred_waits_for_the_block_to_finish() -> None:
    finished = False
    with handle_stop_signals(), pytest.raises(Stopped) as stopped, deferred():
        signal.raise_signal(signal.SIGINT)
        finished = True  # e.g. the manifest written
    assert finished and stopped.value.signum == signal.SIGINT
