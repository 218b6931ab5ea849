"""The CMC bench's serving and scoring side: a replay through the daemon's chain, scored.

:func:`serve` runs a detections replay through ``service.offline.track`` (the daemon's
``Pipeline.process`` with its association, model and tracker, settings as the daemon's
defaults; positions as served live, no fixed-lag smoothing) and keeps, per frame, the
associations (the localizer's output before tracking) and the snapshot (what a client gets).
:func:`score` scores both inside the authors' tracking area against the truth, with the
evaluation pairing of ``bench.real.cmc_data`` for the error attribution (:class:`Ground`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.real import cmc_data
from bench.real.cmc_score import GATE_M, FrameEval, score_frames
from models.data.detections_replay import DetectionsReplay
from models.data.idf1 import identity_scores
from models.data.stream_metrics import StreamFrame, StreamScorer
from models.detector.base import Detections
from service.stages import Association, LocalizationModel, TrackAnchor


@dataclass
class ServedFrame:
    """One frame set's associations (world [A, 2], cameras, detection indices) and the
    snapshot's people (ids [Q], xy [Q, 2])."""

    frame: int
    t: float
    world: np.ndarray
    cameras: list[list[int]]
    detection_index: list[list[int | None]]
    ids: np.ndarray
    xy: np.ndarray


def serve(
    model_dir: Path, replay: Path, oracle: TrueAssociation | None = None
) -> list[ServedFrame]:
    """Every frame set of ``replay`` through the daemon's pipeline with the model of
    ``model_dir``; one :class:`ServedFrame` per frame set. ``oracle``: the association stage
    replaced by the true association (everything else as served)."""
    from models.mom.runtime import MomRuntime
    from service.offline import track as offline
    from service.stages import FrameResult

    runtime = MomRuntime.load(model_dir)
    feed = offline.detections_feed(replay, None)
    settings = offline.offline_settings(None, [str(replay)] * feed.num_cameras)
    pipeline = offline.offline_pipeline(settings, runtime, feed, model_dir)
    results: list[FrameResult] = []
    pipeline.add_listener(results.append)
    if oracle is not None:
        pipeline.chain.associate = oracle
    out = []
    try:
        for frame, frame_set in feed.frame_sets:
            if oracle is not None:
                oracle.frame = frame
            pipeline.process(frame_set)
            r = results[-1]
            people = r.snapshot.people
            out.append(
                ServedFrame(
                    frame=frame,
                    t=float(r.t_capture),
                    world=np.array([a.world for a in r.associations], np.float64).reshape(-1, 2),
                    cameras=[list(a.cameras) for a in r.associations],
                    detection_index=[list(a.detection_index) for a in r.associations],
                    ids=np.array([int(p["id"]) for p in people], np.int64),
                    xy=np.array([[p["x"], p["y"]] for p in people], np.float64).reshape(-1, 2),
                )
            )
    finally:
        pipeline.stop()
    return out


@dataclass
class Ground:
    """The evaluation side of a sequence: truth, and per (frame, camera) the truth id each
    replay box shows (-1: nobody in the area), by ``bench.real.cmc_data.pair_boxes``."""

    truth: cmc_data.Truth
    replay: DetectionsReplay
    owner: dict[tuple[int, int], np.ndarray]
    frames: np.ndarray
    matrices: np.ndarray

    @classmethod
    def build(cls, data: Path, sequence: str, replay_path: Path) -> Ground:
        truth = cmc_data.truth(data, sequence)
        replay = DetectionsReplay.load(replay_path)
        matrices = cmc_data.projections(data)
        owner = {}
        frames = np.unique(truth.frame)
        for f in frames.tolist():
            rows = truth.at(f)
            for k in range(replay.num_cameras):
                boxes, _ = replay.at(f, k)
                who = cmc_data.pair_boxes(matrices[k], truth.world[rows], truth.z_c[rows], boxes)
                owner[(f, k)] = np.where(who >= 0, truth.id[rows][np.maximum(who, 0)], -1)
        return cls(truth, replay, owner, frames, matrices)

    def people_replay(self, path: Path) -> Path:
        """The replay without the boxes of nobody, written to ``path`` (an oracle's input)."""
        keep = np.zeros(self.replay.n, bool)
        for (f, k), owner in self.owner.items():
            keep[self.replay.rows(f, k)[owner >= 0]] = True
        r = self.replay
        DetectionsReplay(
            r.frame[keep], r.camera[keep], r.boxes[keep], r.scores[keep], r.image_size, r.fps
        ).save(path)
        return path

    def views(self, frame: int) -> np.ndarray:
        """Per truth row of ``frame``: cameras with a box of that person."""
        ids = self.truth.id[self.truth.at(frame)]
        counts = np.zeros(len(ids), np.int64)
        for k in range(self.replay.num_cameras):
            counts += np.isin(ids, self.owner.get((frame, k), np.zeros(0, np.int64)))
        return counts

    def boxes_of(self, frame: int, person: int) -> np.ndarray:
        """The person's paired box per camera [K, 4] (NaN: none)."""
        out = np.full((self.replay.num_cameras, 4), np.nan, np.float32)
        for k in range(self.replay.num_cameras):
            hit = np.flatnonzero(self.owner.get((frame, k), np.zeros(0)) == person)
            if len(hit):
                out[k] = self.replay.at(frame, k)[0][hit[0]]
        return out

    def nobody_boxes(self) -> dict[str, float]:
        """Boxes per frame (all cameras) that show no true person of the area; the share of
        them whose calibrated foot point (``cmc_data.floor_points``) lies outside it; and of
        those inside, the share overlapping a true person's expected box (IoU >= 0.1: a second
        or fragment box of someone already paired, which the 0.3 pairing gate leaves unowned)."""
        count = outside = overlapping = 0
        for f in self.frames.tolist():
            rows = self.truth.at(f)
            for k in range(self.replay.num_cameras):
                boxes = self.replay.at(f, k)[0][self.owner[(f, k)] < 0].astype(np.float64)
                inside = cmc_data.in_area(cmc_data.floor_points(self.matrices[k], boxes))
                count += len(boxes)
                outside += int((~inside).sum())
                if inside.any() and len(rows):
                    expected = cmc_data.expected_boxes(
                        self.matrices[k], self.truth.world[rows], self.truth.z_c[rows]
                    )
                    overlapping += int((cmc_data.iou(boxes[inside], expected).max(1) >= 0.1).sum())
        return {
            "nobody_boxes_per_frame": count / len(self.frames),
            "nobody_boxes_foot_outside": outside / count if count else float("nan"),
            "nobody_boxes_inside_overlapping_person": overlapping / (count - outside)
            if count > outside
            else float("nan"),
        }

    def frame_eval(
        self,
        frame: int,
        est_xy: np.ndarray,
        people: list[set[int]] | None = None,
        views: list[int] | None = None,
    ) -> FrameEval:
        rows = self.truth.at(frame)
        inside = cmc_data.in_area(est_xy)
        return FrameEval(
            truth_ids=self.truth.id[rows],
            truth_xy=self.truth.world[rows],
            truth_views=self.views(frame),
            est_xy=np.asarray(est_xy).reshape(-1, 2)[inside],
            est_people=[]
            if people is None
            else [p for p, keep in zip(people, inside, strict=True) if keep],
            est_views=[]
            if views is None
            else [v for v, keep in zip(views, inside, strict=True) if keep],
        )


def stream_scores(
    ground: Ground, stream: dict[int, tuple[np.ndarray, np.ndarray]]
) -> dict[str, Any]:
    """Streamed metrics of ``{frame: (ids, xy)}`` over the truth frames, inside the area."""
    scorer = StreamScorer(GATE_M)
    frames = []
    for f in ground.frames.tolist():
        rows = ground.truth.at(f)
        ids, xy = stream.get(f, (np.zeros(0, np.int64), np.zeros((0, 2))))
        inside = cmc_data.in_area(xy)
        sf = StreamFrame(
            f / cmc_data.FPS,
            ground.truth.id[rows],
            ground.truth.world[rows],
            ids[inside],
            xy[inside],
            ground.views(f),
        )
        scorer.add(sf.t, sf.truth_ids, sf.truth_xy, sf.served_ids, sf.served_xy, sf.views)
        frames.append(sf)
    result = scorer.result()
    return {
        "mota": result["mota"],
        "idf1": identity_scores(frames, GATE_M)["idf1"],
        "id_switches": result["id_switches"],
        "acc_0_3": result["acc@0.3"],
        "stream_precision": result["precision"],
        "stream_recall": result["recall"],
        "stream_matched_mean_m": result["mean"],
        "stream_recall_by_cameras": {c: v["recall"] for c, v in result["by_views"].items()},
    }


def score(ground: Ground, served: list[ServedFrame]) -> dict[str, Any]:
    """Per-frame metrics of the associations and streamed metrics of the snapshots."""
    by_frame = {s.frame: s for s in served}
    evals = []
    for f in ground.frames.tolist():
        s = by_frame.get(f)
        if s is None:
            evals.append(ground.frame_eval(f, np.zeros((0, 2)), [], []))
            continue
        people = []
        for index in s.detection_index:
            who = {int(ground.owner[(f, k)][i]) for k, i in enumerate(index) if i is not None}
            people.append(who - {-1})
        evals.append(ground.frame_eval(f, s.world, people, [len(c) for c in s.cameras]))
    out = score_frames(evals)
    out.update(stream_scores(ground, {s.frame: (s.ids, s.xy) for s in served}))
    out.update(ground.nobody_boxes())
    return out


class TrueAssociation:
    """Association stage answering with the evaluation pairing (an oracle bound): one
    association per true person with a box, localized by the model from exactly their boxes;
    boxes of nobody are dropped; each with the model's covariance, as the real association.
    :func:`serve` sets :attr:`frame` before each frame set (the stage contract has no frame)."""

    def __init__(self, ground: Ground) -> None:
        self.ground = ground
        self.frame = -1

    def __call__(
        self,
        detections: Sequence[Detections],
        runtime: LocalizationModel,
        /,
        *,
        max_error_px: float,
        anchors: Sequence[TrackAnchor] = (),
    ) -> list[Association]:
        cameras = len(detections)
        owners = [
            self.ground.owner.get((self.frame, k), np.zeros(0, np.int64)) for k in range(cameras)
        ]
        people = sorted({int(i) for owner in owners for i in owner if i >= 0})
        if not people:
            return []
        row = {person: p for p, person in enumerate(people)}
        boxes = np.full((len(people), cameras, 4), np.nan, np.float32)
        index: list[list[int | None]] = [[None] * cameras for _ in people]
        for k, owner in enumerate(owners):
            for j, person in enumerate(owner.tolist()):
                if person >= 0:
                    boxes[row[person], k] = detections[k].boxes[j]
                    index[row[person]][k] = j
        world = np.asarray(runtime.localize(boxes), np.float64)
        errors = np.asarray(runtime.reprojection_error(boxes, world))
        cov = np.asarray(runtime.covariance(boxes), np.float64)
        return [
            Association(
                boxes=boxes[p],
                cameras=[k for k in range(cameras) if index[p][k] is not None],
                world=world[p],
                cost=0.0,
                detection_index=index[p],
                errors=errors[p],
                covariance=cov[p],
            )
            for p in range(len(people))
        ]
