"""Person detectors: one batched onnxruntime call for all cameras, boxes in frame pixels.

See :mod:`models.detector.base` for the interface and the registry, ``ssdlite`` for the shipped
default and ``yolov8`` for user-supplied YOLOv8 ONNX exports.
"""

from models.detector.base import (
    Detections,
    PersonDetector,
    available_detectors,
    create_detector,
    register_detector,
)

__all__ = [
    "Detections",
    "PersonDetector",
    "available_detectors",
    "create_detector",
    "register_detector",
]
