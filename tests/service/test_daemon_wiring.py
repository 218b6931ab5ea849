"""What the daemon's composition checks once, and how it opens cameras from typed settings."""

from __future__ import annotations

from pathlib import Path

import pytest

from capture.rig import CameraRig
from capture.sources import V4L2Source, VideoFileSource
from capture.worker import CameraWorker
from common.errors import MomlocError
from service.daemon import build_daemon
from service.pipeline.build import build_rig
from service.settings import DEMO_MODEL_DIR, load_settings
from tests.capture.fakes import write_mjpg


def test_a_model_for_another_camera_count_is_refused_with_one_line() -> None:
    settings = load_settings(
        None,
        cameras=[{"type": "synthetic", "index": k} for k in range(3)],
        synthetic={"preset": "indoor-4cam", "detections": "simulated"},
        model_dir=DEMO_MODEL_DIR,  # trained for 2 cameras
    )
    with pytest.raises(MomlocError, match=r"^model_dir: .*expects 2 cameras, 3 are configured$"):
        build_daemon(settings)


def test_cameras_are_opened_by_their_settings_type(tmp_path: Path) -> None:
    video = write_mjpg(tmp_path / "a.avi", frames=4)
    settings = load_settings(
        None,
        cameras=[
            {"type": "v4l2", "device": "2", "width": 320, "height": 240},
            {"type": "v4l2", "device": "/dev/v4l/by-id/usb-cam-index0"},
            {"type": "file", "path": str(video), "loop": False},
        ],
    )
    rig, player = build_rig(settings)
    assert isinstance(rig, CameraRig) and player is None
    workers = [w for w in rig.workers if isinstance(w, CameraWorker)]
    first, by_id, played = (worker.source for worker in workers)
    assert isinstance(first, V4L2Source) and first.device == 2 and first.width == 320
    assert isinstance(by_id, V4L2Source) and by_id.device == "/dev/v4l/by-id/usb-cam-index0"
    assert isinstance(played, VideoFileSource) and played.path == video and not played.loop
    missing = load_settings(None, cameras=[{"type": "file", "path": str(tmp_path / "no.avi")}])
    with pytest.raises(MomlocError, match=r"no\.avi does not exist"):
        build_rig(missing)


def test_the_detectors_input_growth_is_a_setting() -> None:
    from models.detector.nanodet import NanoDetDetector
    from service.detection.schedule import DetectionScheduler
    from service.pipeline.build import build_detect_stage

    def stage(**detector: object) -> NanoDetDetector:
        settings = load_settings(
            None,
            cameras=[{"type": "v4l2", "device": "0"}],
            detector=detector,
            detection={"schedule": "every_frame"},
        )
        built = build_detect_stage(settings, None)
        assert isinstance(built, DetectionScheduler)
        assert isinstance(built.detector, NanoDetDetector)
        return built.detector

    assert stage().max_shrink == 3.0  # the kind's default
    assert stage(max_shrink=2).max_shrink == 2.0
    with pytest.raises(MomlocError, match=r"detector\.max_shrink: Extra inputs are not permitted"):
        stage(kind="ssdlite", max_shrink=2)  # an option of another kind: the field is named
    with pytest.raises(MomlocError, match="max_shrink"):
        stage(max_shrink=0.5)


def test_the_detectors_runtime_is_a_typed_setting() -> None:
    """``detector.runtime`` and ``detector.precision`` pick NanoDet's inference engine; auto: the
    first installed of the measured preference."""
    from models.detector import runtimes
    from models.detector.nanodet import NanoDetDetector
    from service.detection.schedule import DetectionScheduler
    from service.pipeline.build import build_detect_stage

    def built(detection: dict[str, object], **detector: object) -> object:
        settings = load_settings(
            None, cameras=[{"type": "v4l2", "device": "0"}], detector=detector, detection=detection
        )
        stage = build_detect_stage(settings, None)
        assert isinstance(stage, DetectionScheduler)
        assert isinstance(stage.detector, NanoDetDetector)
        return stage.detector.graph.runtime, stage.detector.graph.precision

    assert built({"schedule": "every_frame"}, runtime="onnxruntime") == ("onnxruntime", "fp32")
    preferred = runtimes.choose_engine("auto", "auto", user_model=False)
    assert built({"schedule": "auto"}) == preferred
    assert built({"schedule": "every_frame"}, threads=1, runtime="auto") == preferred
    fp32 = runtimes.choose_engine("auto", "fp32", user_model=False)
    assert built({"schedule": "every_frame"}, precision="fp32") == fp32
    with pytest.raises(MomlocError, match=r"detector\.precision: Input should be 'auto'"):
        built({"schedule": "every_frame"}, precision="fp16")
    with pytest.raises(MomlocError, match="'onnxruntime' has no int8 model"):
        built({"schedule": "every_frame"}, runtime="onnxruntime", precision="int8")
    with pytest.raises(MomlocError, match=r"detector\.runtime: Input should be 'auto'"):
        built({"schedule": "every_frame"}, runtime="tensorrt")
    with pytest.raises(MomlocError, match=r"detector\.runtime: Extra inputs"):
        built({"schedule": "every_frame"}, kind="ssdlite", runtime="onnxruntime")
