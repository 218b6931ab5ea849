"""Pipeline: chain order, snapshot content, frame dropping, ids on boxes, model hot swap.

Uses a fake rig, fake detector stage and a fake model so that the assertions are exact; the real
detector, model, association and tracker run together in tests/e2e.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

from capture.rig import FrameSet
from capture.worker import CameraState, Frame
from common.errors import MomlocError
from models.detector.base import Detections, PersonDetector
from service.detection.schedule import DetectionScheduler
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.stages import Association
from service.tracking.tracker import Tracker
from tests.service.fake_frames import FunctionStage, frames_at
from tests.service.mom_doubles import ModelDouble


@dataclass
class FakeRig:
    """Every frame_set() call returns a newer set, ``step`` scene frames ahead."""

    step: int = 1
    size: tuple[int, int] = (640, 480)
    seq: int = 0
    started: bool = False
    calls: list[int] = field(default_factory=list)

    def start(self) -> None:
        self.started = True

    def stop(self) -> None:
        self.started = False

    def frame_set(self, after: FrameSet | None = None, timeout: float = 0.0) -> FrameSet:
        self.seq += self.step
        image = np.zeros((self.size[1], self.size[0], 3), np.uint8)
        return frames_at(self.seq, 100.0 + self.seq / 30, (True, True), image)

    def states(self) -> list[CameraState]:
        return [CameraState(True, 30.0, 0.01, 0, None)] * 2


class FakeRuntime(ModelDouble):
    """Positions come from ``fake_associate`` (a box alone localizes nowhere: NaN); every view
    is ``error_px`` off."""

    def __init__(self, cameras: int = 2, size: tuple[int, int] = (640, 480)) -> None:
        self.num_cameras = cameras
        self.image_sizes = np.array([size] * cameras)
        self.error_px = 2.0

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.full((len(boxes), 2), np.nan)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        return np.full(boxes.shape[:2], self.error_px)


def boxes_stage(frame_set: FrameSet) -> list[Detections]:
    """One person per camera whose box x encodes the scene frame (so positions move)."""
    first = frame_set.frames[0]
    assert first is not None
    seq = first.seq
    box = np.array([[100 + seq, 50, 160 + seq, 250]], np.float32)
    return [Detections(b, np.ones(1, np.float32)) for b in (box, box + 10)]


def fake_associate(detections, runtime, max_error_px, anchors=()):
    a = Association(
        boxes=np.stack([d.boxes[0] for d in detections]),
        cameras=[0, 1],
        world=np.array([detections[0].boxes[0, 0] / 100.0, 2.0]),
        cost=1.0,
        detection_index=[0, 0],
    )
    return [a]


def make(rig=None, runtime=None, **kw) -> tuple[Pipeline, Hub]:
    hub = Hub()
    pipeline = Pipeline(
        rig or FakeRig(),
        FunctionStage(kw.pop("detect", boxes_stage), keypoints=kw.pop("keypoints", False)),
        hub,
        num_cameras=2,
        runtime=runtime if runtime is not None else FakeRuntime(),
        tracker=Tracker(fps_hint=30.0),
        associate=fake_associate,
        load_runtime=kw.pop("load_runtime", lambda path: FakeRuntime()),
        **kw,
    )
    return pipeline, hub


def next_set(pipeline: Pipeline) -> FrameSet:
    frame_set = pipeline.rig.frame_set()
    assert frame_set is not None  # a FakeRig always has a newer one
    return frame_set


def test_process_publishes_tracked_people_with_capture_time():
    pipeline, hub = make()
    snaps = [pipeline.process(next_set(pipeline)) for _ in range(10)]
    assert [s.seq for s in snaps] == list(range(1, 11))
    last = hub.latest()
    assert last is snaps[-1]
    assert last.t == pytest.approx(100.0 + 10 / 30)
    (person,) = last.people
    assert set(person) == {"id", "x", "y", "vx", "vy", "confidence", "cameras"}
    assert person["x"] == pytest.approx(1.10, abs=0.02) and person["y"] == pytest.approx(2.0)
    assert person["vx"] == pytest.approx(0.3, abs=0.1)  # 0.01 m per frame at 30 fps
    assert person["cameras"] == [0, 1]
    view = pipeline.view(1)
    assert view.image is not None
    ((box, track_id),) = view.boxes
    assert track_id == person["id"] and box[0] == pytest.approx(120.0)


def test_previews_without_images_keep_boxes_ids_and_size_but_no_frame():
    """Privacy mode: the preview store holds no reference to any frame."""
    pipeline, hub = make(preview_images=False)
    for _ in range(10):
        pipeline.process(next_set(pipeline))
    (person,) = hub.latest().people
    view = pipeline.view(0)
    assert view.image is None and view.size == (640, 480)
    ((box, track_id),) = view.boxes
    assert track_id == person["id"] and box[0] == pytest.approx(110.0)


def test_no_model_publishes_empty_snapshots():
    pipeline, _hub = make()
    pipeline.runtime = None
    snapshot = pipeline.process(next_set(pipeline))
    assert snapshot.people == [] and pipeline.model_info() == {"loaded": False, "path": None}


def test_thread_skips_stale_frames_and_counts_drops():
    rig = FakeRig(step=3)
    pipeline, _hub = make(rig)
    pipeline.start()
    deadline = time.time() + 10
    while pipeline.frames_processed < 5 and time.time() < deadline:
        time.sleep(0.01)
    pipeline.stop()
    assert not rig.started and not pipeline.running
    stats = pipeline.stats()
    assert stats["frames_processed"] >= 5
    # every processed set was 3 frames newer than the last: 2 frames per camera skipped each time
    assert stats["frames_dropped"] == 2 * 2 * (stats["frames_processed"] - 1)
    assert stats["latency_ms"]["p50"] is not None and stats["error"] is None


def test_stage_failure_is_reported_not_fatal():
    calls = {"n": 0}

    def flaky(frame_set):
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("detector exploded")
        return boxes_stage(frame_set)

    pipeline, _hub = make(detect=flaky)
    pipeline.start()
    deadline = time.time() + 10
    while pipeline.frames_processed < 2 and time.time() < deadline:
        time.sleep(0.01)
    pipeline.stop()
    assert pipeline.frames_processed >= 2
    stats = pipeline.stats()
    assert stats["failures"] == 1 and "detector exploded" in stats["last_failure"]
    assert stats["error"] is None  # later iterations succeeded


def test_reload_refuses_mismatched_models_and_keeps_the_old_one(tmp_path):
    models = {
        "three": FakeRuntime(cameras=3),
        "small": FakeRuntime(size=(320, 240)),
        "good": FakeRuntime(),
    }
    original = FakeRuntime()
    pipeline, _ = make(runtime=original, load_runtime=lambda path: models[path.name])
    pipeline.process(next_set(pipeline))  # learns the real image sizes
    with pytest.raises(MomlocError, match="expects 3 cameras, 2 are configured"):
        pipeline.reload_model(tmp_path / "three")
    with pytest.raises(
        MomlocError, match="320x240 images from camera 0, the camera delivers 640x480"
    ):
        pipeline.reload_model(tmp_path / "small")
    assert pipeline.runtime is original
    info = pipeline.reload_model(tmp_path / "good")
    assert pipeline.runtime is models["good"]
    assert info["loaded"] and info["compatible"] and info["num_cameras"] == 2


def test_model_that_does_not_fit_the_frames_is_reported():
    pipeline, _ = make(runtime=FakeRuntime(size=(1280, 720)))
    snapshot = pipeline.process(next_set(pipeline))
    assert snapshot.people == []
    assert "1280x720" in pipeline.stats()["error"]
    assert pipeline.model_info()["compatible"] is False


def test_detector_stage_batches_and_leaves_scores_to_the_detector():
    class Det(PersonDetector):
        def __init__(self) -> None:
            self.batches: list[int] = []

        def detect(self, frames):
            self.batches.append(len(frames))
            boxes = np.array([[0, 0, 10, 20], [5, 5, 50, 90]], np.float32)
            return [Detections(boxes, np.array([0.9, 0.2], np.float32)) for _ in frames]

    det = Det()
    stage = DetectionScheduler(det, mode="every_frame")
    frame = Frame(camera=0, image=np.zeros((4, 4, 3), np.uint8), timestamp=0.0, seq=0)
    out = stage(FrameSet(frames=[frame, None, frame], skew=0.0))
    assert det.batches == [2]
    # the detector applied its own score_threshold already: a second filter here would drop
    # boxes the settings asked to keep (the 0.2 box stands for one just above the threshold)
    assert [o.boxes.shape for o in out] == [(2, 4), (0, 4), (2, 4)]
    assert all(o.keypoints is None for o in out)


def test_detection_listeners_and_alignment_see_every_frame_set():
    pipeline, _ = make()
    seen = []
    listener = lambda t, boxes: seen.append((t, [b.copy() for b in boxes]))  # noqa: E731
    pipeline.add_detection_listener(listener)
    rig = FakeRig()
    for _ in range(3):
        pipeline.process(rig.frame_set())
    pipeline.remove_detection_listener(listener)
    pipeline.process(rig.frame_set())
    assert len(seen) == 3 and seen[0][1][0].shape == (1, 4)
    assert [s.error_px for s in pipeline.camera_watch.alignment.status()] == [2.0, 2.0]


class KeypointRuntime(FakeRuntime):
    observation = "keypoints"

    def reprojection_error(self, boxes, world, keypoints=None):
        assert keypoints is not None and keypoints.shape[-2:] == (17, 3)
        return super().reprojection_error(boxes, world)


def keypoint_stage(frame_set: FrameSet) -> list[Detections]:
    """Like ``boxes_stage``, with one COCO-17 keypoint set per box."""
    out = boxes_stage(frame_set)
    return [Detections(d.boxes, d.scores, np.ones((1, 17, 3), np.float32)) for d in out]


def test_keypoints_reach_association_and_box_only_detectors_refuse_keypoint_models(tmp_path):
    seen = []

    def associate(detections, runtime, max_error_px, anchors=()):
        seen.append([d.keypoints for d in detections])
        (a,) = fake_associate(detections, runtime, max_error_px)
        a.keypoints = np.stack([d.keypoints[0] for d in detections])
        return [a]

    pipeline, _ = make(detect=keypoint_stage, keypoints=True, runtime=KeypointRuntime())
    pipeline.chain.associate = associate
    snapshots = [pipeline.process(next_set(pipeline)) for _ in range(10)]
    assert len(snapshots[-1].people) == 1 and seen[0][0].shape == (1, 17, 3)
    assert pipeline.model_info()["observation"] == "keypoints"
    # the camera-moved check judged the reprojection error with the keypoints too
    assert [s.error_px for s in pipeline.camera_watch.alignment.status()] == [2.0, 2.0]
    # a box-only detector: the keypoint model is refused at reload, the running one stays
    boxes_only, _ = make(load_runtime=lambda path: KeypointRuntime())
    current = boxes_only.runtime
    with pytest.raises(MomlocError, match=r"reads keypoints.*boxes only") as info:
        boxes_only.reload_model(tmp_path / "keypoint-model")
    assert "\n" not in str(info.value) and "keeping the current model" in str(info.value)
    assert boxes_only.runtime is current
    with pytest.raises(MomlocError, match="reads keypoints"):
        boxes_only.check_model(KeypointRuntime(), "model_dir: m")


def test_detector_stage_keeps_each_boxs_keypoints():
    class Det(PersonDetector):
        keypoints = True

        def detect(self, frames):
            boxes = np.array([[0, 0, 10, 20], [5, 5, 50, 90]], np.float32)
            points = np.stack([np.full((17, 3), 1.0), np.full((17, 3), 2.0)]).astype(np.float32)
            return [Detections(boxes, np.array([0.2, 0.9], np.float32), points) for _ in frames]

    stage = DetectionScheduler(Det(), mode="every_frame")
    frame = Frame(camera=0, image=np.zeros((4, 4, 3), np.uint8), timestamp=0.0, seq=0)
    (out,) = stage(FrameSet(frames=[frame], skew=0.0))
    assert stage.keypoints and out.keypoints is not None
    assert out.boxes.tolist() == [[0, 0, 10, 20], [5, 5, 50, 90]]
    assert (out.keypoints[0] == 1.0).all() and (out.keypoints[1] == 2.0).all()


def test_skew_rule_leaves_stale_frames_out_of_fusion():
    """A frame more than max_skew older than the newest (marked stale by the rig) is not fused:
    the set is localized from the fresh cameras and stamped with their capture time."""
    calls = []

    def detect(frame_set):
        calls.append([f is not None for f in frame_set.frames])
        return [Detections.empty() for _ in frame_set.frames]

    pipeline, _ = make(detect=detect)
    pipeline.chain.associate = lambda detections, runtime, max_error_px, anchors=(): []
    image = np.zeros((480, 640, 3), np.uint8)
    frames: list[Frame | None] = [
        Frame(camera=0, image=image, timestamp=10.0, seq=5),  # 120 ms late
        Frame(camera=1, image=image, timestamp=10.12, seq=9),
    ]
    snapshot = pipeline.process(FrameSet(frames=frames, skew=0.12, stale=[True, False]))
    assert calls[-1] == [False, True] and snapshot.t == pytest.approx(10.12)
    assert pipeline.stats()["views_left_out"] == 1
    assert pipeline.view(0).image is None and pipeline.view(1).image is not None
    synced = FrameSet(frames=frames, skew=0.12, stale=[False, False])  # within the bound
    assert pipeline.process(synced).t == pytest.approx(10.0) and calls[-1] == [True, True]


def test_scheduled_detection_carries_keypoints_between_detections():
    """With ``detection.schedule: auto`` the detector runs every few frame sets; the boxes
    carried in between keep their keypoints (moved with the box), so a keypoint model gets
    keypoints on every frame set, not only on the detected ones."""
    from service.detection.schedule import DeferredRunner

    class Walker(PersonDetector):
        keypoints = True

        def detect(self, frames):
            box = np.array([[100, 50, 160, 250]], np.float32)
            points = np.zeros((1, 17, 3), np.float32)
            points[0, :, 0], points[0, :, 1], points[0, :, 2] = 130.0, np.linspace(60, 240, 17), 1
            return [Detections(box, np.ones(1, np.float32), points) for _ in frames]

    clock = SimpleNamespace(t=0.0)
    detector = Walker()
    runner = DeferredRunner(
        lambda job: detector.detect(job.images), lambda: clock.t, cost=lambda job: 0.1
    )
    stage = DetectionScheduler(detector, runner=runner, clock=lambda: clock.t, wall=lambda: clock.t)
    assert stage.keypoints
    image = np.zeros((480, 640, 3), np.uint8)
    outputs = []
    for i in range(12):
        clock.t = i / 30
        frames: list[Frame | None] = [
            Frame(camera=k, image=image, timestamp=clock.t, seq=i) for k in range(2)
        ]
        outputs.append(stage(FrameSet(frames=frames, skew=0.0)))
    later = [d for out in outputs[4:] for d in out]  # after the first detection arrived
    assert later and all(len(d) == 1 for d in later)
    points = [d.keypoints for d in later]
    assert all(k is not None and k.shape == (1, 17, 3) and np.isfinite(k).all() for k in points)
    assert stage.jobs < 12  # most frame sets were carried, not detected
