"""``service.pipeline.failure_log``: one traceback per run of failures, a count per period, an end
line."""

from __future__ import annotations

import logging

from service.pipeline.failure_log import FailureLog


def test_a_run_of_failures_is_one_traceback_a_count_per_period_and_an_end(caplog) -> None:
    caplog.set_level(logging.INFO, logger="test.failures")
    now = [0.0]
    failures = FailureLog(logging.getLogger("test.failures"), "frame sets", 10.0, lambda: now[0])
    for _ in range(95):  # 95 frame sets in 23.5 s
        failures.failed(ValueError("bad input"))
        now[0] += 0.25
    failures.succeeded()
    failures.succeeded()  # no run open: nothing to say
    messages = [r.getMessage() for r in caplog.records]
    assert sum(r.exc_info is not None for r in caplog.records) == 1
    assert messages[0].startswith("frame sets fail: ValueError")
    assert len(messages) == 4  # the traceback, a count at 10 s and at 20 s, the end
    assert messages[1].startswith("41 frame sets failed since ")
    assert messages[1].endswith("(10 s), the last with ValueError: bad input")
    assert messages[2].startswith("81 frame sets failed since ")
    assert messages[3].startswith("frame sets work again after 95 failed since ")

    failures.failed(KeyError("other"))  # a new run gets its own traceback
    assert caplog.records[-1].exc_info is not None and failures.failed_in_run == 1
