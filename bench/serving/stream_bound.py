"""What the detector's reports allow the served stream: an oracle tracker's scores (writes
bench/results/stream_bound.md).

The oracle knows who is who. Where at least one camera's detector reports a person (after the
simulated detector's misses) it serves, per ``MODES`` entry (reports, filter, coasting):

- reports ``truth``: the true position, exactly, with no delay; ``model``: what the stream
  bench's MoM model (:func:`bench.serving.stream_accuracy.train_cached`) makes of that person's own
  boxes (no false boxes, no association errors); ``calibrated``: the same with a calibrated
  localizer and the true cameras (:func:`models.geometry.calibrated_baseline.localize`: triangulated
  box centres where two cameras see whole boxes, else the foot point);
- filter ``none`` (that frame's report), ``causal`` (the median of the person's reports over the
  last ``WINDOW_S``), ``centred`` (within ``± WINDOW_S``, offline only) or ``still`` (while the
  truth stands still, the mean of the person's reports since it stopped: the oracle also knows
  when someone is still, which a tracker can only infer from the same reports, late).

Where no camera reports the person it holds the last report (``hold``) or moves it on at the
last reported velocity over ``VELOCITY_S`` (``extrapolate``), for at most ``--coast-s`` seconds.

Scored by :class:`models.data.stream_metrics.StreamScorer` on the same truth as
:func:`service.offline.stream_eval.run_stream` (people *in view*, whether or not the detector
reports them). The ``truth`` rows bound MOTA and recall of any tracker that holds or extrapolates
through the misses; the ``model`` and ``calibrated`` rows are not bounds (a tracker that weighs each
report by its covariance does better) but show what one frame's boxes say, with association
taken out: together they tell how much of the gap to the issue-14 targets is the misses and how
much the boxes. The standing jitter column (:mod:`models.data.stream_metrics`) is how much the
boxes shake a still person with the association perfect: per frame, smoothed over a second
(``centred``), and averaged over all of their stillness (``still``).

Usage::

    python -m bench.serving.stream_bound [--profile nanodet] [--seeds 7 8] [--frames 600]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bench.report import machine_line
from bench.serving.stream_accuracy import combine, train_cached
from models.data.stream_metrics import STILL_SPEED_MPS, StreamScorer
from models.geometry import calibrated_baseline as baseline
from models.mom.runtime import MomRuntime
from models.simulate import Scene
from service.offline.stream_eval import MIN_VISIBLE_FRACTION, in_view, scene_config

RESULTS = Path(__file__).resolve().parents[1] / "results"
SCENES = (("indoor-2cam", 1), ("indoor-2cam", 3), ("indoor-2cam", 5), ("indoor-4cam", 3),
          ("living-room", 2))  # fmt: skip
VELOCITY_S = 0.3  # the oracle's velocity: its own reported positions over this long
WINDOW_S = 0.5  # the filters' window
# (what the oracle reports where a camera sees the person, filter over time, coasting)
MODES = (
    ("truth", "none", "hold"),
    ("truth", "none", "extrapolate"),
    ("model", "none", "hold"),
    ("model", "causal", "hold"),
    ("model", "centred", "hold"),
    ("model", "still", "hold"),
    ("calibrated", "none", "hold"),
    ("calibrated", "centred", "hold"),
)


def reported_positions(
    scene: Scene, frames: int, source: str, runtime: MomRuntime | None
) -> list[dict[str, np.ndarray]]:
    """Per frame the truth (``want``, ``track``, ``world``, ``views``) and what the oracle's
    ``source`` reports for each person some camera's detector sees (NaN where none does)."""
    projections = scene.projection_matrices()
    out = []
    for i in range(frames):
        obs = scene.observe(i)
        views = np.isfinite(obs.boxes).all(axis=2).sum(axis=1)
        seen = views > 0
        reported = np.full((len(obs.track), 2), np.nan)
        if seen.any():
            if source == "truth":
                reported[seen] = obs.world[seen, :2]
            elif source == "model" and runtime is not None:
                reported[seen] = runtime.localize(obs.boxes[seen])
            else:
                reported[seen] = baseline.localize(
                    obs.boxes[seen], projections, image_size=scene.image_sizes
                )
        out.append(
            {
                "want": in_view(obs.true_boxes, scene.image_sizes, MIN_VISIBLE_FRACTION),
                "track": obs.track.astype(np.int64),
                "world": obs.world[:, :2].astype(np.float64),
                "views": views,
                "reported": reported,
            }
        )
    return out


def filtered(frames: list[dict[str, np.ndarray]], fps: float, kind: str) -> None:
    """Replace each report by the median of the same person's reports over the last
    ``WINDOW_S`` (``causal``) or within ``± WINDOW_S`` (``centred``, offline only), or while
    they stand still by the mean of their reports since they stopped (``still``)."""
    if kind == "none":
        return
    if kind == "still":
        _still_means(frames, fps)
        return
    half = round(WINDOW_S * fps)
    series: dict[int, list[tuple[int, int]]] = {}
    for i, frame in enumerate(frames):
        for p, track in enumerate(frame["track"]):
            series.setdefault(int(track), []).append((i, p))
    for rows in series.values():
        xy = np.array([frames[i]["reported"][p] for i, p in rows])
        index = np.array([i for i, _ in rows])
        for n, (i, p) in enumerate(rows):
            if not np.isfinite(xy[n]).all():
                continue
            lo, hi = i - half, i + (half if kind == "centred" else 0)
            near = (index >= lo) & (index <= hi) & np.isfinite(xy).all(axis=1)
            frames[i]["filtered"] = frames[i].get("filtered", frames[i]["reported"].copy())
            frames[i]["filtered"][p] = np.median(xy[near], axis=0)
    for frame in frames:
        frame["reported"] = frame.pop("filtered", frame["reported"])


def _still_means(frames: list[dict[str, np.ndarray]], fps: float) -> None:
    """The ``still`` filter: a person's report, while their true speed stays below the scorer's
    still speed, replaced by the mean of their reports since it did."""
    since: dict[int, list[np.ndarray]] = {}
    before: dict[int, np.ndarray] = {}
    for frame in frames:
        out = frame["reported"].copy()
        for p, track in enumerate(frame["track"]):
            track, xy = int(track), frame["world"][p]
            moved = before.get(track)
            before[track] = xy
            if moved is None or np.linalg.norm(xy - moved) * fps >= STILL_SPEED_MPS:
                since[track] = []
            if np.isfinite(out[p]).all():
                since[track].append(out[p].copy())
                out[p] = np.mean(since[track], axis=0)
        frame["reported"] = out


def oracle_scores(
    preset: str,
    people: int,
    profile: str,
    seed: int,
    frames: int,
    coast_s: float,
    mode: tuple[str, str, str],
    runtime: MomRuntime | None = None,
) -> dict:
    """The 0.5 m gate's stream metrics of the oracle on one scene run (``runtime``: the
    localizer of the ``model`` source)."""
    source, kind, coasting = mode
    scene = Scene(scene_config(preset, people, profile), seed=seed)
    recorded = reported_positions(scene, frames, source, runtime)
    filtered(recorded, scene.fps, kind)
    scorer = StreamScorer(0.5)
    last: dict[int, list[tuple[float, np.ndarray]]] = {}  # id -> reported (t, xy), recent
    for i, frame in enumerate(recorded):
        t = i / scene.fps
        served_ids, served_xy = [], []
        for p, track in enumerate(frame["track"]):
            track = int(track)
            xy = frame["reported"][p]
            if np.isfinite(xy).all():
                history = [(s, q) for s, q in last.get(track, []) if t - s <= VELOCITY_S]
                last[track] = [*history, (t, xy)]
                served_ids.append(track)
                served_xy.append(xy)
                continue
            history = last.get(track)
            if not history or t - history[-1][0] > coast_s:
                continue
            s1, q1 = history[-1]
            position = q1
            if coasting == "extrapolate" and len(history) > 1 and s1 > history[0][0]:
                s0, q0 = history[0]
                position = q1 + (q1 - q0) / (s1 - s0) * (t - s1)
            served_ids.append(track)
            served_xy.append(position)
        want = frame["want"]
        scorer.add(
            t,
            frame["track"][want],
            frame["world"][want],
            served_ids,
            np.array(served_xy).reshape(-1, 2),
            frame["views"][want],
        )
    return scorer.result()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="nanodet")
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 8])
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--coast-s", type=float, nargs="+", default=[0.5])
    parser.add_argument("--train-frames", type=int, default=3000)
    parser.add_argument("--epochs", type=int, default=150)
    args = parser.parse_args()
    lines = [
        "# Stream bound: an oracle tracker on the simulated detector's reports",
        "",
        machine_line(),
        "",
        f"`python -m bench.serving.stream_bound --profile {args.profile}`, seeds "
        f"{' '.join(map(str, args.seeds))} × {args.frames} frames, 0.5 m gate. The oracle knows "
        "who is who; where some camera's detector reports a person it serves the truth "
        "(`truth`), the stream bench's MoM model on that person's own boxes (`model`) or a "
        "calibrated localizer with the true cameras (`calibrated`), per frame or as a median "
        f"over the last {WINDOW_S:g} s (`causal`) or ± {WINDOW_S:g} s (`centred`, offline), or "
        "while the person stands still the mean of their reports since they stopped (`still`: "
        "the oracle knows when); "
        "where none does it holds (or extrapolates) the last report for at most the coast time "
        "(`bench/serving/stream_bound.py`).",
        "",
        "| scene | people | no camera reports % | coast | reports | filter | coasting | recall % "
        "| MOTA % | matched mean m | Acc@0.3 % | standing jitter cm |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for preset, people in SCENES:
        model = train_cached(preset, args.profile, args.train_frames, args.epochs)
        runtime = MomRuntime.load(model)
        for coast in args.coast_s:
            for mode in MODES:
                runs = [
                    oracle_scores(
                        preset, people, args.profile, s, args.frames, coast, mode, runtime
                    )
                    for s in args.seeds
                ]
                pooled = combine(runs)
                unseen = pooled["by_views"]["0"]["gt"] / pooled["gt"] * 100
                label = "∞" if coast > 1e6 else f"{coast:g} s"
                row = (
                    f"| {preset} | {people} | {unseen:.1f} | {label} | {' | '.join(mode)} | "
                    f"{pooled['recall']:.1f} | {pooled['mota']:.1f} | {pooled['mean']:.3f} | "
                    f"{pooled['acc@0.3']:.1f} | {100 * pooled['jitter_m']:.2f} |"
                )
                print(row, flush=True)
                lines.append(row)
    (RESULTS / "stream_bound.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
