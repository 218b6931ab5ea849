"""`momloc detect IMAGE...`: run the person detector on images, print boxes, write annotated copies.

The quickest check that the detector sees the people in *your* room: take a snapshot from each
camera, run this, and look at ``NAME.detections.jpg``. Images go through the same batched
detector the daemon uses (chunks of ``BATCH`` images per inference call).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # loaded when the command runs: `momloc --help` stays fast
    import numpy as np

    from models.detector import Detections

BATCH = 8


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "detect",
        help="run the person detector on images, print boxes, write annotated copies",
        description="Detect people in images with the shipped NanoDet (or SSDLite, or your "
        "YOLOv8 ONNX).",
    )
    parser.add_argument("images", nargs="+", type=Path, metavar="IMAGE")
    parser.add_argument(
        "--detector", default="nanodet", help="detector type (nanodet, ssdlite, yolov8)"
    )
    parser.add_argument("--model", type=Path, help="ONNX file (required for yolov8)")
    parser.add_argument("--threshold", type=float, help="minimum score (detector default)")
    parser.add_argument(
        "--letterbox",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="pad to square instead of stretching (detector default)",
    )
    parser.add_argument(
        "--max-shrink",
        type=float,
        help="nanodet: shrink larger frames by at most this much (a larger input; detector "
        "default 3; e.g. 100 keeps 320x256 for every frame)",
    )
    parser.add_argument(
        "--keypoints", action="store_true", help="add COCO-17 keypoints on each person"
    )
    parser.add_argument(
        "--keypoint-backend",
        choices=("blazepose", "mediapipe"),
        default="blazepose",
        help="with --keypoints: blazepose (shipped, default) or mediapipe (momloc[keypoints])",
    )
    parser.add_argument("--out-dir", type=Path, help="write annotated copies here")
    parser.add_argument("--no-write", action="store_true", help="only print, write no images")
    parser.add_argument("--json", action="store_true", help="print one JSON object per image")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import cv2

    from common.errors import MomlocError
    from models.detector import create_detector

    images = []
    for path in args.images:
        image = cv2.imread(str(path), cv2.IMREAD_COLOR) if path.is_file() else None
        if image is None:
            reason = "not found" if not path.exists() else "not a readable image"
            raise MomlocError(f"image {path}: {reason}")
        images.append(image)

    options: dict[str, object] = {
        "keypoints": args.keypoints,
        "keypoint_backend": args.keypoint_backend,
    }
    if args.model is not None:
        options["model_path"] = args.model
    if args.threshold is not None:
        options["score_threshold"] = args.threshold
    if args.letterbox is not None:
        options["letterbox"] = args.letterbox
    if args.max_shrink is not None:
        options["max_shrink"] = args.max_shrink
    detector = create_detector(args.detector, **options)

    results = []
    for start in range(0, len(images), BATCH):
        results.extend(detector.detect(images[start : start + BATCH]))

    if args.out_dir is not None:
        args.out_dir.mkdir(parents=True, exist_ok=True)
    for path, image, found in zip(args.images, images, results, strict=True):
        written = None
        if not args.no_write:
            folder = args.out_dir if args.out_dir is not None else path.parent
            written = folder / f"{path.stem}.detections.jpg"
            if not cv2.imwrite(str(written), annotate(image, found)):
                raise MomlocError(f"annotated image {written}: cannot be written")
        report(path, image, found, written, args.json)
    return 0


def report(
    path: Path, image: np.ndarray, found: Detections, written: Path | None, as_json: bool
) -> None:
    height, width = image.shape[:2]
    if as_json:
        record = {
            "image": str(path),
            "width": width,
            "height": height,
            "boxes": [[round(float(v), 1) for v in box] for box in found.boxes],
            "scores": [round(float(s), 4) for s in found.scores],
            "annotated": str(written) if written else None,
        }
        if found.keypoints is not None:
            record["keypoints"] = [
                [[None if v != v else round(float(v), 1) for v in point] for point in person]
                for person in found.keypoints
            ]
        print(json.dumps(record))
        return
    print(f"{path}: {len(found)} {'person' if len(found) == 1 else 'people'} ({width}x{height})")
    for index, (box, score) in enumerate(zip(found.boxes, found.scores, strict=True), 1):
        x0, y0, x1, y1 = (float(v) for v in box)
        print(
            f"  #{index} score {score:.2f}  box {x0:.0f},{y0:.0f},{x1:.0f},{y1:.0f}"
            f"  ({x1 - x0:.0f}x{y1 - y0:.0f} px)"
        )
    if written is not None:
        print(f"  annotated: {written}")


def annotate(image: np.ndarray, found: Detections) -> np.ndarray:
    """A copy of ``image`` with boxes, scores and (if present) keypoints drawn."""
    import cv2
    import numpy as np

    out = image.copy()
    thickness = max(1, round(max(image.shape[:2]) / 320))
    for index, (box, score) in enumerate(zip(found.boxes, found.scores, strict=True)):
        x0, y0, x1, y1 = (round(float(v)) for v in box)
        cv2.rectangle(out, (x0, y0), (x1, y1), (0, 220, 0), thickness)
        label = f"#{index + 1} {score:.2f}"
        cv2.putText(
            out, label, (x0 + 3, max(y0 - 5, 12)), cv2.FONT_HERSHEY_SIMPLEX,
            0.4 * thickness, (0, 220, 0), thickness,
        )  # fmt: skip
        if found.keypoints is not None:
            for x, y, confidence in found.keypoints[index]:
                if np.isfinite(x) and confidence > 0.5:
                    cv2.circle(out, (round(x), round(y)), 2 * thickness, (0, 0, 255), -1)
    return out
