"""Frames in: sources (V4L2 webcam, video file, synthetic scene), one worker thread per camera
keeping only the newest frame, watchdog and reconnect, and multi-camera frame sets.

``capture`` imports only two leaf modules of the rest of the project, ``common.errors`` (the one
user-facing error type) and ``common.atomic`` (the one atomic file writer), which import nothing
of it themselves: synthetic cameras take any scene with the
``capture.synthetic.RenderedScene`` shape, and opening a camera from settings is the service's
job (``service.daemon``). ``tests/test_layering.py`` enforces this.
"""

from capture.rig import CameraRig, FrameSet
from capture.sources import FrameSource, V4L2Source, VideoFileSource
from capture.worker import CameraState, CameraWorker, Frame

__all__ = [
    "CameraRig",
    "CameraState",
    "CameraWorker",
    "Frame",
    "FrameSet",
    "FrameSource",
    "V4L2Source",
    "VideoFileSource",
]
