"""The set-up's state machine: one step at a time, a refusal names the running step."""

from __future__ import annotations

import threading

import pytest

from common.errors import MomlocError
from service.setup.steps import SetupConflict, SetupSteps


@pytest.mark.parametrize("running", ["record", "train", "verify"])
@pytest.mark.parametrize("asked", ["record", "train", "verify"])
def test_every_step_is_refused_while_another_runs(running, asked):
    steps = SetupSteps()
    steps.begin(running)
    with pytest.raises(SetupConflict) as refused:
        steps.begin(asked)
    assert isinstance(refused.value, MomlocError)  # answered 409, not a crash
    text = str(refused.value)
    assert ("already running" in text) if asked == running else ("cannot start while" in text)
    assert steps.active == running
    if asked != running:
        steps.end(asked)  # releasing a step that does not hold the claim changes nothing
        assert steps.active == running
    steps.end(running)
    assert steps.active is None
    steps.begin(asked)
    assert steps.active == asked


def test_only_one_of_many_simultaneous_claims_wins():
    steps, won, barrier = SetupSteps(), [], threading.Barrier(8)

    def claim(step):
        barrier.wait()
        try:
            steps.begin(step)
            won.append(step)
        except SetupConflict:
            pass

    threads = [threading.Thread(target=claim, args=(s,)) for s in ["record", "train"] * 4]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(won) == 1 and steps.active == won[0]
