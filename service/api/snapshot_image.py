"""Camera previews: the newest frame as a JPEG with detector boxes and track ids drawn on it, or
the boxes alone as JSON (what the pages draw on an empty background under ``privacy:
positions_only``, when no view holds an image).

Drawing happens on request (in FastAPI's thread pool), on a copy, so the pipeline thread never
pays for previews nobody is looking at.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from pydantic import BaseModel, Field


class PreviewBox(BaseModel):
    """One detector box of a camera preview."""

    box: list[float] = Field(description="xmin, ymin, xmax, ymax in pixels of the frame.")
    id: int | None = Field(description="Track id the box fed; null: not assigned to a track.")


class CameraBoxes(BaseModel):
    """A camera's newest boxes, the JSON twin of its snapshot JPEG (no pixels)."""

    width: int | None = Field(description="Frame width in pixels; null before the first frame.")
    height: int | None = Field(description="Frame height in pixels; null before the first frame.")
    boxes: list[PreviewBox] = Field(description="Boxes of the newest previewed frame.")


def camera_boxes_of(view: Any) -> CameraBoxes:
    """``view``'s finite boxes and ids with the frame size."""
    width, height = view.size if view.size is not None else (None, None)
    boxes = [
        PreviewBox(box=[round(float(v), 1) for v in box[:4]], id=track_id)
        for box, track_id in view.boxes
        if np.all(np.isfinite(box[:4]))
    ]
    return CameraBoxes(width=width, height=height, boxes=boxes)


def id_colour(track_id: int | None) -> tuple[int, int, int]:
    """Stable BGR colour per id (grey for boxes not assigned to a track); matches the map page."""
    if track_id is None:
        return (160, 160, 160)
    hue = (track_id * 47) % 180
    hsv = np.array([[[hue, 200, 255]]], np.uint8)
    b, g, r = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


def render_camera_jpeg(view: Any, *, quality: int = 75, width: int | None = None) -> bytes | None:
    """JPEG bytes of ``view.image`` with ``view.boxes`` drawn; None when there is no frame yet."""
    if view.image is None:
        return None
    image = np.ascontiguousarray(view.image).copy()
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    for box, track_id in view.boxes:
        if not np.all(np.isfinite(box)):
            continue
        x0, y0, x1, y1 = (round(float(v)) for v in box[:4])
        colour = id_colour(track_id)
        cv2.rectangle(image, (x0, y0), (x1, y1), colour, 2)
        if track_id is not None:
            label = f"#{track_id}"
            (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 2)
            top = max(y0 - th - 6, 0)
            cv2.rectangle(image, (x0, top), (x0 + tw + 6, top + th + 6), colour, -1)
            cv2.putText(
                image, label, (x0 + 3, top + th + 2), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 2
            )
    if width is not None and width != image.shape[1]:
        height = max(1, round(image.shape[0] * width / image.shape[1]))
        image = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    return data.tobytes() if ok else None
