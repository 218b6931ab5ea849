"""The detector benchmark's three data sets, all as 640×480 BGR frames with true person boxes.

- **vtest**: frames of OpenCV's pedestrian video ``vtest.avi`` (Debian ``opencv-doc``) with the
  hand-checked boxes of ``bench/data/vtest_people.json``. The video is never copied into the repo:
  it is read from the package's path (installed with apt-get when missing, like a test set-up)
  and checked against the SHA-256 recorded with the boxes, so the boxes always meet the frames
  they were drawn on. Frames are resized 768×576 → 640×480 (same 4:3 aspect) so that box heights
  mean what they mean for the product's webcams.
- **simulator**: drawn frames of :mod:`models.simulate` (``Scene.render``) with
  ``true_boxes`` as truth; occlusion by nearer people and truncation at the border are derived
  from the geometry with the same meaning as the hand flags.
- **photos**: scikit-image's two photographs with a person pasted at known sizes and places into
  a plain frame (labels in ``bench/data/skimage_people.json``), plus its photographs without people
  for false positives.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from bench.detector.metrics import Truth
from common.errors import MomlocError

if TYPE_CHECKING:
    from models.simulate import Scene

DATA = Path(__file__).resolve().parents[1] / "data"
VTEST_LABELS = DATA / "vtest_people.json"
PHOTO_LABELS = DATA / "skimage_people.json"
FRAME_SIZE = (640, 480)
ORIGINS = ("accepted", "corrected", "added")
# Occlusion fractions for simulated people: flagged like the hand labels (≈15 % hidden), ignored
# when most of the body is hidden or cut off (nobody could demand a box there).
OCCLUDED_FROM, IGNORE_FROM, MIN_VISIBLE = 0.15, 0.7, 0.3
SIM_PLAN: tuple[tuple[str, dict[str, object]], ...] = (
    ("indoor-4cam", {}),
    ("office-3cam", {}),
    ("living-room", {}),
    ("single-cam", {}),
    ("indoor-4cam", {"people": 6, "room": (14.0, 12.0)}),  # more and smaller people
)
PHOTO_HEIGHTS = (40, 60, 80, 100, 130, 160, 200, 260, 340, 420)
PHOTO_ANCHORS = ((0.0, 1.0), (0.5, 0.5), (1.0, 1.0))


@dataclass(frozen=True)
class Sample:
    """One frame for the detector: ``name`` says where it came from."""

    name: str
    image: np.ndarray
    truth: Truth


def load_labels(path: Path) -> dict:
    with open(path) as stream:
        return json.load(stream)


def truth_from_rows(rows: Sequence[dict]) -> Truth:
    return Truth.of(
        [r["box"] for r in rows] if rows else np.zeros((0, 4)),
        [r["occluded"] for r in rows],
        [r["truncated"] for r in rows],
        [r.get("ignore", False) for r in rows],
    )


def annotation_problems(doc: dict) -> list[str]:
    """Everything wrong with a vtest label file (schema, boxes in the frame, counts), or []."""
    problems = []
    video = doc.get("video", {})
    width, height = video.get("width"), video.get("height")
    if not isinstance(width, int) or not isinstance(height, int):
        return ["video.width / video.height missing"]
    frames = doc.get("frames", {})
    if sorted(int(k) for k in frames) != doc.get("frame_indices"):
        problems.append("frame_indices do not list the annotated frames")
    counts = dict.fromkeys((*ORIGINS, "occluded", "truncated", "ignore", "boxes"), 0)
    for key, rows in frames.items():
        if not 0 <= int(key) < video.get("frames", 0):
            problems.append(f"frame {key} outside the video")
        for i, row in enumerate(rows):
            where = f"frame {key} box {i}"
            if set(row) != {"box", "occluded", "truncated", "ignore", "origin"}:
                problems.append(f"{where}: keys {sorted(row)}")
                continue
            x0, y0, x1, y1 = row["box"]
            if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
                problems.append(f"{where}: {row['box']} not inside {width}x{height}")
            if row["origin"] not in ORIGINS:
                problems.append(f"{where}: origin {row['origin']!r}")
            else:
                counts[row["origin"]] += 1
            for flag in ("occluded", "truncated", "ignore"):
                if not isinstance(row[flag], bool):
                    problems.append(f"{where}: {flag} is not true/false")
                counts[flag] += bool(row[flag])
            touches = x0 <= 0 or y0 <= 0 or x1 >= width or y1 >= height
            if touches != row["truncated"] and not row["ignore"]:
                problems.append(
                    f"{where}: truncated={row['truncated']} but touches border={touches}"
                )
            counts["boxes"] += 1
    expected = doc.get("counts", {})
    for key, value in counts.items():
        if expected.get(key) != value:
            problems.append(f"counts.{key} = {expected.get(key)} but the boxes give {value}")
    if expected.get("frames") != len(frames):
        problems.append(f"counts.frames = {expected.get('frames')} but {len(frames)} frames")
    return problems


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def ensure_vtest(doc: dict, install: bool = True) -> Path:
    """The annotated video (Debian's ``opencv-doc``, installed when missing), checksum-checked."""
    path = Path(doc["video"]["path"])
    if not path.is_file() and install and shutil.which("apt-get"):
        subprocess.run(
            ["apt-get", "install", "-y", "-q", doc["video"]["debian_package"]],
            check=False,
            capture_output=True,
        )
    if not path.is_file():
        raise MomlocError(f"{path}: missing (install it with: apt-get install opencv-doc)")
    if file_sha256(path) != doc["video"]["sha256"]:
        raise MomlocError(f"{path}: checksum differs from the one the boxes were drawn on")
    return path


def vtest_samples(doc: dict | None = None) -> list[Sample]:
    """The annotated vtest frames at 640×480, boxes scaled with them."""
    doc = doc or load_labels(VTEST_LABELS)
    path = ensure_vtest(doc)
    wanted = {int(k): rows for k, rows in doc["frames"].items()}
    scale = FRAME_SIZE[0] / doc["video"]["width"]
    capture = cv2.VideoCapture(str(path))
    samples, index = [], 0
    try:
        while len(samples) < len(wanted):
            ok, frame = capture.read()
            if not ok:
                raise MomlocError(f"{path}: ended at frame {index} before all annotated frames")
            if index in wanted:
                image = cv2.resize(frame, FRAME_SIZE, interpolation=cv2.INTER_AREA)
                truth = truth_from_rows(wanted[index]).scaled(scale)
                samples.append(Sample(f"vtest:{index}", image, truth))
            index += 1
    finally:
        capture.release()
    return samples


def simulated_truth(
    true_boxes: np.ndarray, depth: np.ndarray, image_size: tuple[int, int]
) -> Truth:
    """Truth for one rendered camera image: ``true_boxes`` [P, 4] unclipped (NaN: unseen),
    ``depth`` [P] of each body along the optical axis (nearer people occlude farther ones)."""
    seen = np.isfinite(true_boxes).all(1)
    full = true_boxes[seen]
    width, height = image_size
    clipped = full.copy()
    clipped[:, [0, 2]] = clipped[:, [0, 2]].clip(0, width)
    clipped[:, [1, 3]] = clipped[:, [1, 3]].clip(0, height)
    area = lambda b: (b[:, 2] - b[:, 0]).clip(0) * (b[:, 3] - b[:, 1]).clip(0)  # noqa: E731
    visible = area(clipped) / np.maximum(area(full), 1e-9)
    occlusion = np.zeros(len(full))
    near = depth[seen]
    for i, box in enumerate(clipped):
        x0, y0, x1, y1 = np.floor(box).astype(int)
        if x1 <= x0 or y1 <= y0:
            continue
        mask = np.zeros((y1 - y0, x1 - x0), bool)
        for j in np.flatnonzero(near < near[i]):
            a = np.floor(clipped[j]).astype(int) - [x0, y0, x0, y0]
            mask[max(a[1], 0) : max(a[3], 0), max(a[0], 0) : max(a[2], 0)] = True
        occlusion[i] = mask.mean()
    truncated = visible < 0.98
    tall = clipped[:, 3] - clipped[:, 1]
    ignore = (visible < MIN_VISIBLE) | (occlusion >= IGNORE_FROM) | (tall < 8)
    return Truth(clipped, occlusion >= OCCLUDED_FROM, truncated, ignore)


def simulator_samples(
    frames_per_scene: int = 6, seeds: Sequence[int] = (1, 2), step: int = 45
) -> Iterator[Sample]:
    """Drawn frames of several scenes and seeds (every 640×480 camera), people of all sizes."""
    from models.simulate import Scene, get_config

    for preset, changes in SIM_PLAN:
        config = get_config(preset, **changes)
        tag = preset + ("-more" if changes else "")
        for seed in seeds:
            frames = range(0, frames_per_scene * step, step)
            yield from scene_samples(Scene(config, seed), frames, f"{tag}/s{seed}", FRAME_SIZE)


def scene_samples(
    scene: Scene, frames: Iterable[int], tag: str, size: tuple[int, int] | None = None
) -> Iterator[Sample]:
    """Each camera's drawn frame at ``frames`` with its truth (only cameras of ``size`` when
    given); nearer people occlude farther ones by the depth of their joints' centre."""
    for frame in frames:
        observed = scene.observe(frame)
        centre = observed.joints.mean(axis=1)  # [P, 3]
        for k, camera in enumerate(scene.cameras_at(frame)):
            if size is not None and tuple(camera.image_size) != size:
                continue
            depth = (centre @ camera.R.T + camera.t)[:, 2]
            truth = simulated_truth(observed.true_boxes[:, k], depth, camera.image_size)
            yield Sample(f"sim:{tag}/f{frame}/c{k}", scene.render(frame, k), truth)


def photo_samples(doc: dict | None = None) -> list[Sample]:
    """Photographs with a person pasted at several heights and places, and photographs without."""
    from models.detector.validation import FRAME_SIZE as PASTE_SIZE
    from models.detector.validation import background, paste, photo

    assert PASTE_SIZE == FRAME_SIZE
    doc = doc or load_labels(PHOTO_LABELS)
    samples = []
    for name, rows in doc["photos"].items():
        image, truth = photo(name), truth_from_rows(rows)
        top, bottom = truth.boxes[:, 1].min(), truth.boxes[:, 3].max()
        for height in PHOTO_HEIGHTS:
            scale = height / (bottom - top)
            for i, anchor in enumerate(PHOTO_ANCHORS):
                frame, (x0, y0) = paste(image, background(i), scale, anchor)
                boxes = truth.boxes * scale + [x0, y0, x0, y0]
                inside = boxes.copy()
                inside[:, [0, 2]] = inside[:, [0, 2]].clip(0, FRAME_SIZE[0])
                inside[:, [1, 3]] = inside[:, [1, 3]].clip(0, FRAME_SIZE[1])
                cut = truth.truncated | (np.abs(inside - boxes).max(1) > 0.5)
                pasted = Truth(inside, truth.occluded, cut, truth.ignore)
                samples.append(Sample(f"photo:{name}@{height}/{i}", frame, pasted))
    for name in doc["no_people"]:
        image = photo(name)
        scale = min(FRAME_SIZE[0] / image.shape[1], FRAME_SIZE[1] / image.shape[0])
        frame, _ = paste(image, background(0), scale, (0.5, 0.5))
        samples.append(Sample(f"photo:{name}", frame, Truth.of(np.zeros((0, 4)))))
    return samples
