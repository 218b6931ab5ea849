"""Where the streamed MOTA goes: every false positive, miss and id switch at 0.5 m attributed
to a cause (writes a markdown table: ``bench/results/stream_breakdown.md``).

The same run as ``bench/serving/stream_accuracy.py``
(:func:`service.offline.stream_eval.run_stream`, a model trained on another recording of the preset
and profile, cached in ``momloc-bench-cache``), with a tap on every frame: the simulator's truth
tells which person (or which false box) each association's boxes came from,
:meth:`service.tracking.tracker.Tracker.hidden` which tracks are held but not served, and a second
:class:`models.data.stream_metrics.StreamScorer` the frame's matches (its totals are checked against
the run's own).

Causes, per served position left unmatched (FP):

- ``ghost``: the track's boxes are all detector false positives;
- ``mis-association``: its measurement fuses boxes of different people or a person and a false
  box (a wrong pair across cameras, a far-off fused position);
- ``duplicate``: its boxes are of a person another served track already matches;
- ``single-view range``: one camera, the measurement itself > 0.5 m off (a lone box's depth);
- ``multi-view error``: two or more cameras of one person, measurement > 0.5 m off;
- ``filter off``: the measurement is within 0.5 m but the track is not (inertia, a track dragged
  away earlier, robust down-weighting);
- ``coasting drift``: no measurement this frame, the prediction is off.

Per truth person left unmatched (FN): ``unseen, not coasted`` (no detector reports them and no
track follows them), ``coasting, too far off``, ``tentative`` (their track is not confirmed yet),
``ghost-suppressed`` (their track is held back by the ghost check), ``track off: <FP cause>`` (a
served track follows their boxes but is > 0.5 m off; counted as an FP too), ``in another
track`` (their boxes were fused into an association served as someone else), ``no track`` (rest).

Id switches: ``lost, new id`` (the former id is no longer served), ``taken over`` (the former
id is still served, elsewhere).

Usage::

    python -m bench.serving.stream_breakdown --profile nanodet --seeds 7 8 --frames 600 \\
        [--variant default[,key=value...]] [--out bench/results/stream_breakdown.md]
"""

from __future__ import annotations

import argparse
import os
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from bench.serving.stream_accuracy import RESULTS, train_cached, variant
from models.data.stream_metrics import StreamScorer
from models.mom.runtime import MomRuntime
from models.simulate import FrameObservation, Scene
from service.offline.stream_eval import MIN_VISIBLE_FRACTION, in_view, run_stream, scene_config
from service.stages import Association, Track
from service.tracking.tracker import Tracker

GATE_M = 0.5
FALSE = -1  # label of a detector false positive


def box_labels(association: Association, obs: FrameObservation) -> list[int]:
    """Per seen camera of ``association``: the person whose detected box it is, or FALSE."""
    out = []
    for k in association.cameras:
        box = np.asarray(association.boxes[k], dtype=np.float32)
        people = obs.boxes[:, k].astype(np.float32)
        same = np.flatnonzero(np.all(people == box[None], axis=1))
        out.append(int(obs.track[same[0]]) if len(same) else FALSE)
    return out


def measurement_cause(labels: list[int], world: np.ndarray, truth: dict[int, np.ndarray]) -> str:
    """Why a measurement of one person's boxes leaves a track off (or: it is fine)."""
    if len(set(labels)) > 1:
        return "mis-association"
    person = labels[0]
    if person == FALSE:
        return "ghost"
    if person not in truth:  # a person out of view (sliver of a box): not expected
        return "ghost"
    if np.linalg.norm(world - truth[person]) <= GATE_M:
        return "filter off"
    return "single-view range" if len(labels) == 1 else "multi-view error"


class Breakdown:
    """Frame tap: attributes the frame's FP, FN and id switches (see the module docstring)."""

    def __init__(self, scene: Scene, tracker: Tracker) -> None:
        self.scene, self.tracker = scene, tracker
        self.scorer = StreamScorer(GATE_M)
        self.fp: Counter[str] = Counter()
        self.fn: Counter[str] = Counter()
        self.switches: Counter[str] = Counter()
        self.source: dict[int, list[int]] = {}  # track id -> labels of its last measurement
        self.last: dict[int, int] = {}  # truth id -> served id last matched

    def __call__(self, i: int, associations: list[Association], tracks: list[Track]) -> None:
        obs = self.scene.observe(i)
        want = in_view(obs.true_boxes, self.scene.image_sizes, MIN_VISIBLE_FRACTION)
        ids = obs.track[want]
        xy = obs.world[want, :2]
        views = np.isfinite(obs.boxes).all(axis=2).sum(axis=1)[want]
        truth = {int(o): p for o, p in zip(ids, xy, strict=True)}
        labels = {id(a): box_labels(a, obs) for a in associations}

        def measured(
            track: Track,
        ) -> Association | None:  # this frame's association of a track, or None (coasting)
            if track.coasting or track.frame != i or track.association is None:
                return None
            return associations[track.association]

        for tr in tracks:
            a = measured(tr)
            if a is not None:
                self.source[tr.id] = labels[id(a)]
        served_xy = np.array([[tr.x, tr.y] for tr in tracks]).reshape(-1, 2)
        pairs = self.scorer.add(i, ids, xy, [tr.id for tr in tracks], served_xy, views)
        matched_truth = {int(ids[r]): tracks[c].id for r, c in pairs}
        matched_served = {c for _, c in pairs}
        served_ids = {tr.id for tr in tracks}

        for o, h in matched_truth.items():
            if o in self.last and self.last[o] != h:
                lost = self.last[o] not in served_ids
                self.switches["lost, new id" if lost else "taken over"] += 1
            self.last[o] = h

        off: dict[int, str] = {}  # truth id -> cause of the served track following them, off
        for c, tr in enumerate(tracks):
            if c in matched_served:
                continue
            cause = self._fp_cause(tr, measured(tr), labels, truth, matched_truth)
            self.fp[cause] += 1
            people = [p for p in self.source.get(tr.id, []) if p != FALSE]
            if cause not in ("ghost", "duplicate") and people:
                off.setdefault(people[0], cause)

        hidden: dict[int, str] = {}
        for tr, why in self.tracker.hidden():
            a = measured(tr)
            for p in labels[id(a)] if a is not None else []:
                hidden.setdefault(p, why)
        in_assoc = {p: a for a in associations for p in labels[id(a)] if p != FALSE}
        serving = {self._person(self.source.get(tr.id, [])) for tr in tracks}
        for r, o in enumerate(ids):
            o = int(o)
            if o in matched_truth:
                continue
            if views[r] == 0:
                self.fn["coasting, too far off" if o in off else "unseen, not coasted"] += 1
            elif o in off:
                self.fn[f"track off: {off[o]}"] += 1
            elif o in hidden:
                self.fn["ghost-suppressed" if hidden[o] == "ghost" else "tentative"] += 1
            elif o in in_assoc and o not in serving:
                self.fn["in another track"] += 1
            else:
                self.fn["no track"] += 1

    @staticmethod
    def _person(labels: list[int]) -> int | None:
        people = [p for p in labels if p != FALSE]
        return people[0] if people and len(set(labels)) == 1 else None

    def _fp_cause(
        self,
        tr: Track,
        a: Association | None,
        labels: dict[int, list[int]],
        truth: dict[int, np.ndarray],
        matched_truth: dict[int, int],
    ) -> str:
        source = self.source.get(tr.id, [FALSE])
        if all(p == FALSE for p in source):
            return "ghost"
        person = self._person(source)
        if person is not None and person in matched_truth:
            return "duplicate"
        if a is None:
            return "coasting drift"
        return measurement_cause(labels[id(a)], np.asarray(a.world, float), truth)


def run(
    runtime: MomRuntime,
    preset: str,
    people: int,
    profile: str | None,
    frames: int,
    seeds: list[int],
    spec: str,
) -> dict:
    """Breakdown and stream metrics pooled over ``seeds``."""
    config = scene_config(preset, people, profile)
    options, use_cov, use_bias = variant(spec)
    total: dict[str, Counter[str]] = {"fp": Counter(), "fn": Counter(), "switches": Counter()}
    metrics = {"gt": 0, "tp": 0, "fp": 0, "fn": 0, "id_switches": 0}
    for seed in seeds:
        tracker = Tracker(fps_hint=config.fps, **options)
        tap = Breakdown(Scene(config, seed=seed), tracker)
        scores = run_stream(
            runtime,
            config,
            seed,
            frames,
            tracker=tracker,
            use_covariance=use_cov,
            view_bias=use_bias,
            on_frame=tap,
            gates=(GATE_M,),
        )[GATE_M]
        for key in metrics:
            metrics[key] += scores[key]
        mine = tap.scorer.result()
        if (mine["fp"], mine["fn"], mine["id_switches"]) != (
            scores["fp"],
            scores["fn"],
            scores["id_switches"],
        ):
            raise RuntimeError("breakdown scorer disagrees with run_stream's")
        total["fp"] += tap.fp
        total["fn"] += tap.fn
        total["switches"] += tap.switches
    return {"metrics": metrics, **total}


def table(result: dict) -> str:
    m = result["metrics"]
    gt = max(m["gt"], 1)
    mota = 100.0 * (1 - (m["fn"] + m["fp"] + m["id_switches"]) / gt)
    lines = [
        f"gt {m['gt']} person-frames, tp {m['tp']}, fp {m['fp']}, fn {m['fn']}, "
        f"id switches {m['id_switches']}; MOTA {mota:.1f} %\n",
        "| kind | cause | count | MOTA points |",
        "|---|---|---|---|",
    ]
    for kind, key in (("FP", "fp"), ("FN", "fn"), ("id switch", "switches")):
        for cause, n in result[key].most_common():
            lines.append(f"| {kind} | {cause} | {n} | {100.0 * n / gt:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--profile", default="nanodet")
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 8])
    parser.add_argument("--scene", default="indoor-2cam:3", help="preset:people")
    parser.add_argument("--variant", default="default", help="name[,key=value...]")
    parser.add_argument("--train-frames", type=int, default=3000)
    parser.add_argument("--epochs", type=int, default=150)
    parser.add_argument("--out", type=Path, default=RESULTS / "stream_breakdown.md")
    args = parser.parse_args(argv)
    preset, people = args.scene.split(":")[0], int(args.scene.split(":")[1])
    runtime = MomRuntime.load(train_cached(preset, args.profile, args.train_frames, args.epochs))
    result = run(runtime, preset, people, args.profile, args.frames, args.seeds, args.variant)
    text = (
        f"# Streamed MOTA breakdown\n\n`python -m bench.serving.stream_breakdown --profile "
        f"{args.profile} --seeds {' '.join(map(str, args.seeds))} --frames {args.frames} "
        f"--scene {args.scene} --variant {args.variant}` on {datetime.now(UTC):%Y-%m-%d %H:%M} "
        f"UTC, {os.cpu_count()} cores shared (gate {GATE_M} m; MOTA points: count per 100 truth "
        "person-frames).\n\n" + table(result)
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
