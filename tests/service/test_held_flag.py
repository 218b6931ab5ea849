"""The time hysteresis behind the camera-moved verdicts."""

from service.camera_health.held_flag import HeldFlag


def test_turns_on_and_off_only_after_holding() -> None:
    flag = HeldFlag(hold_s=2.0)
    assert not flag.update(0.0, True)
    assert not flag.update(1.9, True)
    assert flag.update(2.0, True)
    assert flag.update(3.0, False)  # not yet held off
    assert not flag.update(5.0, False)


def test_an_interruption_restarts_the_clock() -> None:
    flag = HeldFlag(hold_s=2.0)
    flag.update(0.0, True)
    flag.update(1.5, False)
    assert not flag.update(3.0, True)
    assert flag.update(5.0, True)
