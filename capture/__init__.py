"""Frames in: sources (V4L2 webcam, video file, synthetic scene), one worker thread per camera
keeping only the newest frame, watchdog and reconnect, and multi-camera frame sets.

``capture`` imports only ``models.errors`` from the rest of the project (never ``service``).
"""

from capture.rig import CameraRig, FrameSet
from capture.sources import FrameSource, V4L2Source, VideoFileSource, open_source
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
    "open_source",
]
