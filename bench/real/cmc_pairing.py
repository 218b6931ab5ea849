"""Real detector boxes paired with true people in the CMC room, and the same for a simulated room.

The CMC data (Ong et al., "A Bayesian Filter for Multi-view 3D Multi-object Tracking with
Occlusion Handling", IEEE TPAMI 2020; ``../shared/data/cmc``, evaluation only, read from
``--data``) gives a floor position per person and frame, not a box. So each true person is
projected with the camera's P: the floor point (x, y, 0) and a head point (x, y, 2 z_c), z_c
being the centre height of the annotated ellipsoid that sits on the floor. Their image rows
bound a *reference box* ``h`` tall, 0.4 h wide about the floor point's column. Per frame and
camera the detector's boxes are assigned to the reference boxes by the Hungarian method on
``1 - IoU``, gated at IoU >= :data:`IOU_GATE`: a loose gate, because a real box is wider than
0.4 h when the arms swing and the reference box is only a guide to *which* box is whose.

:func:`simulated_frames` turns a simulated scene into the same :class:`Frames` (the mid-hip
floor point, :data:`ANNOTATED_HEAD` of the person's stature as head height,
``FrameObservation.reported`` as the detector's boxes), so the real and the simulated room are
measured by one code path (``bench.real.cmc_detector`` measures, ``bench.real.sim_vs_real``
compares).

**The head point is the annotation's, not the stature.** 2 z_c sits below a real person's head
top: the real boxes' top edges lie 0.09-0.13 h above it (median per height bin,
``bench/results/cmc_detector_measurements.md``) where a tight box of a simulated body ends at its
stature (+0.01 h), and the ``cmc`` profile takes the detector's top edge as unbiased; and the
real people's 2 z_c average 1.55 m, 0.90 of the simulated statures' 1.725 m. With the stature
as the simulated head point, the reference boxes of the simulated room stood taller than the
real ones: a farther person's head showed less above a nearer one, the covered fraction read
higher, 13.9 % of the simulated people were covered >= 85 % against 7.0 % of the real ones (at
matched spacing), and the occlusion table fitted at those fractions missed too many
(``bench/results/sim_vs_real_occlusion.md``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from models.simulate import Scene

SEQUENCES = {"CMC1": "J_1_1", "CMC2": "J_5_2"}
AREA = (2.03, 6.3, 0.0, 3.41)  # the authors' tracking area (x, y metres)
ROOM = (7.67, 3.41)
IMAGE = (1920, 1024)
FPS = 4.0
IOU_GATE = 0.3
WIDTH = 0.4  # reference box width, fraction of its height
_GRID = 8  # occlusion sample grid per side
_BODY = 0.7  # the nearer person's reference box narrowed to its body, as the simulator does
ANNOTATED_HEAD = 0.9  # the CMC annotation's head point 2 z_c over the stature (module docstring)


@dataclass(frozen=True)
class Frames:
    """One sequence: per frame the people in the set-up area [P, 4] (x, y, head z, id) and per
    camera the detector's boxes [M, 4] (xmin, ymin, xmax, ymax); the cameras' P [K, 3, 4]."""

    name: str
    people: list[np.ndarray]
    boxes: list[list[np.ndarray]]
    projections: np.ndarray
    image: tuple[int, int] = IMAGE
    fps: float = FPS


@dataclass(frozen=True)
class Pairs:
    """Per (frame, person, camera): the reference box and what the detector did about it."""

    frame: np.ndarray  # [N] frame index
    person: np.ndarray  # [N] id
    camera: np.ndarray  # [N]
    reference: np.ndarray  # [N, 4] reference box (unclipped)
    visible: np.ndarray  # [N] floor point in front and reference box overlapping the image
    truncated: np.ndarray  # [N] fraction of the reference box outside the image
    occluded: np.ndarray  # [N] fraction covered by nearer people's reference bodies
    box: np.ndarray  # [N, 4] matched detection, NaN when none
    unmatched: list[list[np.ndarray]]  # per frame, per camera: boxes matched to nobody [U, 4]


def load_real(data: Path, sequence: str) -> Frames | None:
    """CMC1 or CMC2 from ``data``/cmc, or None when the files are absent."""
    root = data / "cmc"
    code = SEQUENCES[sequence]
    gt_path = root / "gt" / f"GT_{code}_WORLD_CENTROID.txt"
    if not gt_path.is_file():
        return None
    gt = np.loadtxt(gt_path)
    matrices = json.loads((root / "calibration" / "P_matrices.json").read_text())
    projections = np.array([matrices[f"cam{k}"] for k in range(1, 5)], float)
    frames = int(gt[:, 0].max())
    people = [gt[gt[:, 0] == f + 1][:, [7, 8, 9, 1]] * [1, 1, 2, 1] for f in range(frames)]
    boxes: list[list[np.ndarray]] = [[] for _ in range(frames)]
    for k in range(1, 5):
        det = np.loadtxt(root / "detections_mot" / f"DET_{code}_Cam{k}.txt", ndmin=2)
        xyxy = np.column_stack([det[:, 2:4], det[:, 2:4] + det[:, 4:6]])
        for f in range(frames):
            boxes[f].append(xyxy[det[:, 0] == f + 1])
    return Frames(sequence, people, boxes, projections)


def simulated_frames(scene: Scene, frames: int, name: str) -> Frames:
    """A simulated scene as :class:`Frames`: the labelled people (those in its set-up area)
    with :data:`ANNOTATED_HEAD` of their stature as head height, and every box each camera
    reports."""
    heights = ANNOTATED_HEAD * scene.walkers.heights
    people, boxes = [], []
    for i in range(frames):
        obs = scene.observe(i)
        ids = np.arange(len(obs.world), dtype=float)
        people.append(np.column_stack([obs.world, heights, ids]))
        boxes.append([obs.reported(k)[0] for k in range(scene.num_cameras)])
    size = tuple(int(v) for v in scene.image_sizes[0])
    return Frames(name, people, boxes, scene.projection_matrices(), (size[0], size[1]), scene.fps)


def crowd_size(recording: Frames) -> int:
    """The number of people in the area as the recording's own people see it: per frame the
    count weighted by the count (Σ n² / Σ n), rounded. A simulated recording of the room holds
    that many (``bench.real.sim_vs_real``, the occlusion fit of ``bench.real.cmc_detector``).

    Why not the mean over frames: every figure compared is a share of person-frames (a camera
    share, MODA, MOTA), and how hidden a person is grows with how many stand around them. CMC2
    fills up over its first 110 frames and then holds all 10 for 151; its mean over frames, 8.0,
    put the simulated crowd below the one 73 % of its person-frames stand in: the simulated
    share of people boxed by one camera was 2.6 % at 8 people and is 3.7 % at 9, the real 3.7 %
    (``bench/results/sim_vs_real.md``, the only row that was outside ±20 %)."""
    counts = np.array([len(p) for p in recording.people], np.float64)
    return round(float((counts**2).sum() / max(counts.sum(), 1.0)))


def project(matrix: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels [N, 2] and depth [N] of world points [N, 3] through a 3x4 matrix."""
    h = np.column_stack([points, np.ones(len(points))]) @ matrix.T
    depth = h[:, 2] * np.sign(np.linalg.det(matrix[:, :3]))
    return h[:, :2] / h[:, 2:3], depth


def floor_point(matrix: np.ndarray, pixel: np.ndarray) -> np.ndarray:
    """Floor points (z = 0) [N, 2] under image points [N, 2] (the calibrated foot point)."""
    homography = matrix[:, [0, 1, 3]]
    h = np.linalg.solve(homography, np.column_stack([pixel, np.ones(len(pixel))]).T).T
    return h[:, :2] / h[:, 2:3]


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """[A, B] intersection over union of xyxy boxes."""
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(hi - lo, 0, None).prod(-1)
    area_a = (a[:, 2:] - a[:, :2]).prod(-1)
    area_b = (b[:, 2:] - b[:, :2]).prod(-1)
    return inter / (area_a[:, None] + area_b[None, :] - inter)


def _covered(box: np.ndarray, nearer: np.ndarray) -> float:
    """Share of ``box`` [4] covered by the bodies (narrowed boxes) of ``nearer`` [Q, 4]."""
    if not len(nearer):
        return 0.0
    g = (np.arange(_GRID) + 0.5) / _GRID
    x = box[0] + (box[2] - box[0]) * g
    y = box[1] + (box[3] - box[1]) * g
    xs, ys = np.meshgrid(x, y)
    centre = (nearer[:, 0] + nearer[:, 2]) / 2
    half = (nearer[:, 2] - nearer[:, 0]) * _BODY / 2
    inside = (
        (xs[..., None] >= centre - half)
        & (xs[..., None] <= centre + half)
        & (ys[..., None] >= nearer[:, 1])
        & (ys[..., None] <= nearer[:, 3])
    )
    return float(inside.any(-1).mean())


def pair(frames: Frames) -> Pairs:
    """Reference boxes of every person in every camera and frame, matched to detections."""
    rows: dict[str, list] = {k: [] for k in ("frame", "person", "camera", "reference", "visible",
                                             "truncated", "occluded", "box")}  # fmt: skip
    unmatched: list[list[np.ndarray]] = []
    w, h = frames.image
    for f, (people, per_camera) in enumerate(zip(frames.people, frames.boxes, strict=True)):
        unmatched.append([])
        for k, dets in enumerate(per_camera):
            p = frames.projections[k]
            n = len(people)
            foot, depth = project(p, np.column_stack([people[:, :2], np.zeros(n)]))
            head, _ = project(p, people[:, :3])
            tall = foot[:, 1] - head[:, 1]
            ref = np.column_stack([foot[:, 0] - WIDTH / 2 * tall, head[:, 1],
                                   foot[:, 0] + WIDTH / 2 * tall, foot[:, 1]])  # fmt: skip
            clipped = np.column_stack([np.clip(ref[:, 0::2], 0, w), np.clip(ref[:, 1::2], 0, h)])
            clipped = clipped[:, [0, 2, 1, 3]]
            area = (ref[:, 2:] - ref[:, :2]).prod(-1)
            inside = np.clip(clipped[:, 2:] - clipped[:, :2], 0, None).prod(-1)
            visible = (depth > 0) & (tall > 0) & (inside > 0)
            truncated = np.where(visible, 1 - inside / np.where(area > 0, area, 1), 1.0)
            occluded = np.array(
                [_covered(ref[i], ref[visible & (depth < depth[i] - 0.1)]) for i in range(n)]
            )
            matched = np.full((n, 4), np.nan)
            used = np.zeros(len(dets), bool)
            if n and len(dets):
                overlap = iou(np.where(visible[:, None], ref, np.nan), dets)
                overlap = np.nan_to_num(overlap)
                r, c = linear_sum_assignment(-overlap)
                good = overlap[r, c] >= IOU_GATE
                matched[r[good]] = dets[c[good]]
                used[c[good]] = True
            unmatched[-1].append(dets[~used])
            for key, value in (("frame", np.full(n, f)), ("person", people[:, 3]),
                               ("camera", np.full(n, k)), ("reference", ref),
                               ("visible", visible), ("truncated", truncated),
                               ("occluded", occluded), ("box", matched)):  # fmt: skip
                rows[key].append(value)
    cat = {key: np.concatenate(value) for key, value in rows.items()}
    return Pairs(
        frame=cat["frame"].astype(int),
        person=cat["person"].astype(int),
        camera=cat["camera"].astype(int),
        reference=cat["reference"].reshape(-1, 4),
        visible=cat["visible"].astype(bool),
        truncated=cat["truncated"],
        occluded=cat["occluded"],
        box=cat["box"].reshape(-1, 4),
        unmatched=unmatched,
    )


def in_area(points: np.ndarray, area: tuple[float, float, float, float] = AREA) -> np.ndarray:
    """[N] whether floor points [N, 2] lie in the set-up area."""
    x, y = points[:, 0], points[:, 1]
    return (x >= area[0]) & (x <= area[1]) & (y >= area[2]) & (y <= area[3])


def in_room(points: np.ndarray, room: tuple[float, float] = ROOM) -> np.ndarray:
    """[N] whether floor points [N, 2] lie in the room."""
    x, y = points[:, 0], points[:, 1]
    return (x >= 0) & (x <= room[0]) & (y >= 0) & (y <= room[1])


def outside_people(matrix: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Calibrated foot points [M, 2] of boxes [M, 4] (bottom centre) and [M] whether each
    stands in the room but outside the set-up area: a person the area was not set up for."""
    foot = floor_point(matrix, np.column_stack([(boxes[:, 0] + boxes[:, 2]) / 2, boxes[:, 3]]))
    return foot, in_room(foot) & ~in_area(foot)
