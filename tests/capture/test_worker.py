"""CameraWorker: newest-frame slot, real decoding path, watchdog, reconnect with back-off."""

from __future__ import annotations

import itertools
import time

import pytest

from capture import CameraWorker, Frame, VideoFileSource
from tests.capture.fakes import FaultySource, ManualClock, frame_number, wait_until, write_mjpg


@pytest.fixture
def workers():
    started: list[CameraWorker] = []

    def make(source, **options) -> CameraWorker:
        worker = CameraWorker(source, camera=len(started), **options)
        started.append(worker)
        worker.start()
        return worker

    yield make
    for worker in started:
        worker.stop()


def test_mjpg_file_frames_flow_through_the_worker(tmp_path, workers):
    worker = workers(VideoFileSource(write_mjpg(tmp_path / "cam.avi"), fps=100.0))
    seen: list[Frame] = []
    frame = None
    while len(seen) < 20:
        frame = worker.wait_for_frame(frame.seq if frame else -1, timeout=10.0)
        assert frame is not None, "no frame within 10 s"
        seen.append(frame)
    images = [f.image for f in seen if f.image is not None]
    assert len(images) == len(seen) and all(i.shape == (480, 640, 3) for i in images)
    assert all(b.seq > a.seq and b.timestamp >= a.timestamp for a, b in itertools.pairwise(seen))
    # Decoded content follows the file (frames may be skipped, never reordered within a loop).
    numbers = [frame_number(image) for image in images]
    assert all(0 <= n < 12 for n in numbers)
    state = worker.state()
    assert state.connected and state.error is None and state.fps > 0 and state.frames >= 20
    assert abs(time.time() - seen[-1].timestamp) < 60  # wall clock, not monotonic


def test_slow_consumer_gets_the_newest_frame_never_a_queue(workers):
    source = FaultySource(fps=200.0)
    worker = workers(source)
    assert worker.wait_for_frame(timeout=10.0) is not None
    for _ in range(3):
        time.sleep(0.3)  # a consumer far slower than the camera
        produced = source.reads
        frame = worker.latest()
        assert frame.seq >= produced - 2  # the newest (or the one being published), not old
    assert wait_until(lambda: worker.state().frames > 3 * 10)


def test_stall_is_reported_within_two_intervals_and_recovers(workers):
    source = FaultySource(fps=20.0, read_timeout=0.3)
    worker = workers(source)
    assert wait_until(lambda: worker.state().frames > 10)
    fps = worker.state().fps
    assert worker.stall_timeout(fps) == pytest.approx(2 / fps)
    assert worker.stall_timeout(200.0) == pytest.approx(0.05)  # the jitter floor (min_stall)
    source.paused.set()
    assert wait_until(lambda: not worker.state().connected)
    state = worker.state()
    assert state.last_frame_age > worker.stall_timeout(state.fps) - 1e-9
    assert "stalled" in state.error or "no frame" in state.error
    assert wait_until(lambda: worker.state().stalls >= 1)
    assert wait_until(lambda: source.opens >= 2)  # the read timed out: closed and reopened
    source.paused.clear()
    assert wait_until(lambda: worker.state().connected)
    assert worker.state().reconnects >= 1


def test_connected_always_means_a_fresh_frame(workers):
    source = FaultySource(fps=100.0, read_timeout=0.05)
    worker = workers(source)
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        source.paused.set() if int(time.monotonic() * 10) % 3 == 0 else source.paused.clear()
        state = worker.state()
        if state.connected:  # connected ⇔ age within 2 intervals at the rate it reports
            assert state.last_frame_age <= worker.stall_timeout(state.fps) + 1e-9
        elif state.last_frame_age is not None and state.error and "stalled" in state.error:
            assert state.last_frame_age > worker.stall_timeout(state.fps) - 1e-9
        time.sleep(0.003)


def test_read_errors_reopen_the_source(workers):
    source = FaultySource(fps=100.0)
    worker = workers(source)
    first = worker.wait_for_frame(timeout=10.0)
    source.fail_reads = 3
    assert wait_until(lambda: worker.state().reconnects >= 3)
    frame = worker.wait_for_frame(first.seq + 5, timeout=10.0)
    assert frame is not None and worker.state().connected
    assert source.opens >= 4


BACK_OFF = [0.05, 0.1, 0.2, 0.2, 0.2, 0.2]  # backoff=0.05 doubling up to max_backoff=0.2


def capture_waits(clock: ManualClock, name: str) -> list[float]:
    return [seconds for thread, seconds in clock.waits if thread == f"capture-{name}"]


def test_vanished_camera_comes_back_and_others_keep_running(workers):
    flaky, steady = FaultySource("flaky"), FaultySource("steady")
    clock = ManualClock()  # the flaky camera's time: its back-off, one wait at a time
    a = workers(flaky, backoff=0.05, max_backoff=0.2, clock=clock)
    b = workers(steady)
    assert a.wait_for_frame(timeout=10.0) and b.wait_for_frame(timeout=10.0)
    assert capture_waits(clock, "flaky") == []  # streaming: no waits
    opens = flaky.opens
    flaky.gone.set()
    # closed and reopened at once (a failed open), then retried after each back-off wait
    assert [clock.step() for _ in BACK_OFF] == BACK_OFF
    assert wait_until(lambda: flaky.opens == opens + 1 + len(BACK_OFF))
    state = a.state()
    assert not state.connected and "open failed" in state.error
    # the flaky camera sits in a back-off wait; the other one streams on
    before = b.latest().seq
    assert wait_until(lambda: b.latest().seq > before + 10) and b.state().connected
    flaky.gone.clear()
    last = a.latest().seq
    assert clock.step() == 0.2  # the next attempt opens it
    assert a.wait_for_frame(last, timeout=10.0) is not None
    assert a.state().connected and a.state().reconnects == 1 and a.state().error is None


def test_a_camera_that_opens_but_never_streams_is_retried_with_back_off(workers):
    source = FaultySource("mute")
    source.mute.set()
    clock = ManualClock()
    worker = workers(source, backoff=0.05, max_backoff=0.2, clock=clock)
    start = clock.time()
    # each attempt opens, reads nothing and closes; then 0.05, 0.1, 0.2, 0.2, ... s of waiting
    assert [clock.step() for _ in BACK_OFF] == BACK_OFF
    assert clock.time() - start == pytest.approx(sum(BACK_OFF))  # 0.95 s: 7 opens, not a loop
    assert wait_until(lambda: source.opens == 1 + len(BACK_OFF))  # then waits for the next step
    assert not worker.state().connected and "no frame" in worker.state().error
    source.mute.clear()
    clock.step()
    assert worker.wait_for_frame(timeout=10.0) is not None
    assert worker.state().connected


def test_stop_closes_the_source(workers):
    source = FaultySource()
    worker = workers(source)
    assert worker.wait_for_frame(timeout=10.0)
    worker.stop()
    assert not source.is_open
    assert not any(t.is_alive() for t in worker._threads)
