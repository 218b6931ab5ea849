"""Detection scheduling: never a queue, the newest frame set wins, every frame set is published.

Time is a hand-moved clock and the detector's cost a model (:class:`DeferredRunner`), so the
outcomes are the schedule's, not the machine's load.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np
import pytest

from capture.rig import FrameSet
from capture.worker import Frame
from models.detector.base import Detections
from service.detection.box_carrier import CarriedDetections, box_iou
from service.detection.schedule import (
    DeferredRunner,
    DetectionJob,
    DetectionScheduler,
    ThreadRunner,
)
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from tests.service.fake_frames import FPS, BoxWorld, Clock, FakeDetector, NoRig


def jobs(detector):
    """The detector as a runner calls it: on a job's images."""
    return lambda job: detector.detect(job.images)


def _scheduler(world: BoxWorld, cost: float, **options) -> tuple[DetectionScheduler, Clock]:
    """A scheduler on a hand clock; frames reach it on time (wall clock = the frame's stamp)."""
    clock = Clock()
    detector = FakeDetector(world)
    runner = DeferredRunner(jobs(detector), clock, cost=lambda job: cost)
    options.setdefault("wall", clock)
    return DetectionScheduler(detector, runner=runner, clock=clock, **options), clock


def _calls(scheduler: DetectionScheduler) -> list[list[tuple[int, int]]]:
    """The (frame, camera) pairs of each call of the scheduler's fake detector."""
    assert isinstance(scheduler.detector, FakeDetector)
    return scheduler.detector.calls


def _run(scheduler: DetectionScheduler, clock: Clock, world: BoxWorld, frames: int) -> list:
    out = []
    for i in range(frames):
        clock.t = i / FPS
        out.append(scheduler(world.frame_set(i)))
        for carrier in scheduler.carriers:  # this frame set, not an older one
            assert carrier.time == pytest.approx(i / FPS)
    return out


def test_slow_detector_never_queues_and_always_gets_the_newest_frame_set() -> None:
    world = BoxWorld()
    scheduler, clock = _scheduler(world, cost=0.09)  # ~3 frame slots per call
    published = _run(scheduler, clock, world, 60)
    calls = _calls(scheduler)
    # one call at a time, each on the frame set that was newest when the detector became free
    assert [c[0][0] for c in calls] == list(range(0, 60, 3))
    assert all(c == [(c[0][0], 0), (c[0][0], 1)] for c in calls)
    # every frame set was published, with a box per camera once the first result was in
    assert len(published) == 60
    assert all(len(d) == 1 for out in published[3:] for d in out)
    assert all(len(d) == 0 for out in published[:3] for d in out)


def test_published_boxes_are_those_of_their_own_frame_set() -> None:
    """Results arrive 3 frames late; the boxes published are carried to the current frame."""
    world = BoxWorld()
    scheduler, clock = _scheduler(world, cost=0.09)
    published = _run(scheduler, clock, world, 45)
    for i, out in enumerate(published[9:], start=9):
        for k, det in enumerate(out):
            assert np.abs(det.boxes[0] - world.box(i, k)).max() < 3.0, (i, k)
            stale = world.box(i - 3, k)  # what the late detection itself said
            assert np.abs(stale - world.box(i, k)).max() >= 12
            assert det.age[0] > 0  # carried, and marked as such


def test_very_slow_detector_still_publishes_every_frame_set_with_carried_boxes() -> None:
    world = BoxWorld()
    scheduler, clock = _scheduler(world, cost=0.25)  # ~7.5 frame slots
    published = _run(scheduler, clock, world, 60)
    assert len(_calls(scheduler)) == 8  # frames 0, 8, 16, ..., 56
    boxes = [out[0] for out in published[16:]]
    assert all(len(d) == 1 for d in boxes)
    errors = [np.abs(d.boxes[0] - world.box(i, 0)).max() for i, d in enumerate(boxes, start=16)]
    assert max(errors) < 4.0
    assert max(float(d.age[0]) for d in boxes) >= 8 / FPS


def test_carried_boxes_expire_once_the_detector_stops_finding_them() -> None:
    world = BoxWorld()
    clock = Clock()
    detector = FakeDetector(world, gone_from=12)  # the person is still drawn, never found again
    runner = DeferredRunner(jobs(detector), clock, cost=lambda job: 0.09)
    scheduler = DetectionScheduler(detector, runner=runner, clock=clock)
    published = _run(scheduler, clock, world, 40)
    counts = [len(out[0]) for out in published]
    # calls on frames 12, 15 and 18 find nobody; their results arrive at 15, 18 and 21: the third
    # miss in a row (more than max_misses = 2) removes the box
    assert counts[3:21] == [1] * 18
    assert counts[21:] == [0] * 19


def test_late_frame_sets_are_carried_without_flow() -> None:
    world = BoxWorld()
    on_time, clock = _scheduler(world, cost=0.09)
    _run(on_time, clock, world, 10)
    assert on_time.stats()["flow_skipped_share"] == 0.0
    late, clock = _scheduler(world, cost=0.09, wall=lambda: clock.t + 0.05)
    published = _run(late, clock, world, 20)
    assert late.stats()["flow_skipped_share"] == 1.0
    assert all(len(d) == 1 for out in published[3:] for d in out)  # the filter still carries


def test_flow_is_dropped_while_it_costs_more_than_its_budget(monkeypatch) -> None:
    from service.detection.box_carrier import BoxCarrier

    world = BoxWorld()
    scheduler, clock = _scheduler(world, cost=0.09, flow_budget_s=0.005)
    advance = BoxCarrier.advance

    def slow_flow(self, t, image=None):  # flow costs 10 ms of the hand clock per camera frame
        if image is not None:
            clock.t += 0.010
        return advance(self, t, image)

    monkeypatch.setattr(BoxCarrier, "advance", slow_flow)
    for i in range(60):
        clock.t = i / FPS
        scheduler(world.frame_set(i))
    stats = scheduler.stats()
    assert stats["flow_ms"] == pytest.approx(10.0)
    # measured on the first frame set, then only on every 30th one
    assert stats["flow_skipped_share"] == pytest.approx(58 / 60, abs=0.02)


def test_duty_cycle_leaves_time_between_calls() -> None:
    world = BoxWorld()
    scheduler, clock = _scheduler(world, cost=0.09, max_duty=0.5)
    _run(scheduler, clock, world, 40)
    starts = [c[0][0] for c in _calls(scheduler)]
    assert starts == list(range(0, 40, 6))  # 3 slots busy, then as long again idle
    assert scheduler.stats()["detector_ms"] == pytest.approx(90.0)


def test_alternating_cameras() -> None:
    world = BoxWorld(cameras=3)
    scheduler, clock = _scheduler(world, cost=0.02, cameras_per_call=1)
    _run(scheduler, clock, world, 12)
    cameras = [camera for call in _calls(scheduler) for _, camera in call]
    assert all(len(call) == 1 for call in _calls(scheduler))
    assert cameras[:6] == [0, 1, 2, 0, 1, 2]


def test_alternating_slow_detector_keeps_every_cameras_boxes() -> None:
    """Each camera's turn comes every other call: its boxes must outlive two calls."""
    world = BoxWorld(cameras=2)
    scheduler, clock = _scheduler(world, cost=0.25, cameras_per_call=1)
    published = _run(scheduler, clock, world, 60)
    assert all(len(d) == 1 for out in published[16:] for d in out)


def test_every_frame_mode_detects_inline() -> None:
    world = BoxWorld()
    clock = Clock()
    detector = FakeDetector(world)
    scheduler = DetectionScheduler(detector, mode="every_frame", clock=clock)
    published = _run(scheduler, clock, world, 5)
    assert [c[0][0] for c in detector.calls] == [0, 1, 2, 3, 4]
    for i, out in enumerate(published):
        np.testing.assert_array_equal(out[1].boxes[0], world.box(i, 1))
        assert out[1].age.tolist() == [0.0]
    assert scheduler.runner is None


def test_runners_refuse_a_second_job() -> None:
    job = DetectionJob(((0, 0.0, np.zeros((4, 4, 3), np.uint8)),))
    clock = Clock()
    deferred = DeferredRunner(lambda job: [Detections.empty()], clock, cost=lambda j: 1.0)
    deferred.submit(job)
    with pytest.raises(RuntimeError, match="never queued"):
        deferred.submit(job)
    assert deferred.poll() is None
    clock.t = 1.0
    assert deferred.poll() is not None and not deferred.busy()

    release = threading.Event()

    def blocking(job):
        release.wait(10)
        return [Detections.empty()]

    runner = ThreadRunner(blocking, nice=5)
    runner.submit(job)
    with pytest.raises(RuntimeError, match="never queued"):
        runner.submit(job)
    release.set()
    result = None
    for _ in range(500):
        result = runner.poll()
        if result is not None:
            break
        threading.Event().wait(0.01)
    assert result is not None and result.error is None and result.cost_s >= 0
    runner.close()
    runner.submit(job)  # restartable after close (the pipeline can be started again)
    runner.close()


def test_detector_error_reaches_the_pipeline_thread() -> None:
    def failing(job):
        raise ValueError("bad frame")

    clock = Clock()
    world = BoxWorld()
    scheduler = DetectionScheduler(
        FakeDetector(world), runner=DeferredRunner(failing, clock, cost=lambda j: 0.0), clock=clock
    )
    with pytest.raises(ValueError):
        scheduler(world.frame_set(0))  # DeferredRunner runs at submit


def test_pipeline_runs_the_scheduled_stage() -> None:
    world = BoxWorld()
    scheduler, clock = _scheduler(world, cost=0.05)
    pipeline = Pipeline(NoRig(), scheduler, Hub(), num_cameras=2, shift_threaded=False)
    for i in range(6):
        clock.t = i / FPS
        pipeline.process(world.frame_set(i))
    detection = pipeline.stats()["detection"]
    assert detection["schedule"] == "auto" and detection["jobs"] == 3
    assert detection["box_age_ms"] > 0
    pipeline.stop()


def test_real_detector_on_rendered_frames_produces_boxes() -> None:
    """Shipped SSDLite on the simulator's drawn frames, scheduled: detected and carried boxes."""
    from models.detector import create_detector
    from models.simulate import Scene, get_config

    scene = Scene(get_config("indoor-2cam", people=3), seed=7)
    detector = create_detector("ssdlite", threads=1)
    clock = Clock()
    runner = DeferredRunner(jobs(detector), clock, cost=lambda job: 0.06)
    scheduler = DetectionScheduler(detector, runner=runner, clock=clock)
    found = []
    for i in range(8):
        clock.t = i / FPS
        frames: list[Frame | None] = [
            Frame(camera=k, image=scene.render(i, k), timestamp=i / FPS, seq=i) for k in range(2)
        ]
        out = scheduler(FrameSet(frames=frames, skew=0.0))
        truth = np.asarray(scene.observe(i).true_boxes)
        for k, det in enumerate(out):
            boxes = truth[:, k][np.all(np.isfinite(truth[:, k]), axis=1)]
            if len(det) and len(boxes):
                found.append((i, float(box_iou(det.boxes, boxes).max(axis=1).max())))
    assert scheduler.jobs >= 3
    assert {i for i, _ in found} >= {3, 4, 5, 6, 7}  # boxes on frames no call started on
    assert max(iou for _, iou in found) > 0.5


def test_daemon_builds_the_scheduled_stage_from_settings() -> None:
    from service.demo import demo_settings
    from service.pipeline.build import build_detect_stage
    from service.settings import load_settings

    settings = demo_settings(detections="rendered")
    stage = build_detect_stage(settings, None)
    assert isinstance(stage, DetectionScheduler)
    assert stage.mode == "auto" and stage.runner is not None
    inline = settings.model_copy(
        update={"detection": settings.detection.model_copy(update={"schedule": "every_frame"})}
    )
    every_frame = build_detect_stage(inline, None)
    assert isinstance(every_frame, DetectionScheduler)
    assert every_frame.mode == "every_frame" and every_frame.runner is None
    with pytest.raises(Exception, match="detection"):
        load_settings(None, cameras=[{"type": "synthetic", "index": 0}], detection={"often": 1})


def test_a_job_looks_again_at_known_small_people_in_windows():
    """With a window refiner the job carries the boxes known when it was made, and a small
    person the full pass misses is found in its window (real NanoDet, pasted photograph)."""
    from models.detector import create_detector
    from models.detector.nanodet import NanoDetDetector
    from models.detector.preprocessing import box_iou as iou
    from models.detector.validation import person_frame
    from models.detector.windows import WindowRefiner

    detector = create_detector("nanodet")
    assert isinstance(detector, NanoDetDetector)
    frame, truth = person_frame("camera", 55, anchor=(0.1, 0.9))
    assert (
        not len(detector.detect([frame])[0])
        or iou(truth, detector.detect([frame])[0].boxes).max() < 0.5
    )
    refiner = WindowRefiner(detector.resized((96, 160)))
    scheduler = DetectionScheduler(detector, refiner=refiner, runner=_NoRunner())
    carried = [CarriedDetections((truth + 3)[None].astype(np.float32), np.ones(1, np.float32))]
    frames = [Frame(camera=0, image=frame, timestamp=1.0, seq=0)]
    job = scheduler._job(frames, carried)
    assert job is not None and len(job.priors) == 1
    (found,) = scheduler.detect_job(job)
    assert iou(truth, found.boxes).max() > 0.7
    without = DetectionScheduler(detector, runner=_NoRunner())
    plain = without._job(frames, carried)
    assert plain is not None and plain.priors == ()


class _NoRunner:
    def busy(self) -> bool:
        return False

    def submit(self, job) -> None:
        raise AssertionError("not used")

    def poll(self):
        return None

    def close(self) -> None:
        pass


def test_windows_need_a_detector_of_any_input_size():
    from common.errors import MomlocError
    from service.pipeline.build import build_detect_stage
    from service.settings import Settings

    settings = Settings.model_validate(
        {
            "cameras": [{"type": "file", "path": "/nonexistent.avi"}],
            "detector": {"kind": "ssdlite"},
            "detection": {"windows": 2},
        }
    )
    with pytest.raises(MomlocError, match=r"detection\.windows"):
        build_detect_stage(settings, None)


def test_boxes_are_kept_as_the_detector_scored_them() -> None:
    """The detector's own score_threshold is the one filter: the scheduler adds none."""

    class LowScores(FakeDetector):
        def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
            found = super().detect(frames)
            return [Detections(d.boxes, np.full(len(d), 0.05, np.float32)) for d in found]

    world = BoxWorld()
    scheduler = DetectionScheduler(LowScores(world), mode="every_frame", clock=Clock())
    out = scheduler(world.frame_set(0))
    assert [len(d) for d in out] == [1, 1]
    assert out[0].scores.tolist() == pytest.approx([0.05])
