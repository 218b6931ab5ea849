"""Where the product puts people who sit, crouch and lie: per-frame and streamed error by posture
(writes bench/results/postures.md).

Scenes (:mod:`models.simulate.postures`, :mod:`models.simulate.furniture`), simulated boxes with
the shipped detector's profile (nanodet), 15 fps:

- ``lounge``: the furnished living room (two 640×480 wide-angle webcams): one person on the sofa
  behind the coffee table the whole time, another walking, waiting at the window, crouching and
  sitting in the armchair (preset ``lounge``);
- ``lounge-falls``: the same room, someone walking who falls at three places in turn, lies there
  for 20 s and gets up, while another sits on the sofa;
- ``demo-lounge``: the demo's 10 × 10 m room and cameras (preset ``demo-lounge``: three walkers
  and someone on the sofa), and ``demo-falls``: a faller there.

Models: ``usual`` is trained the usual way on walking and standing people of the same cameras
(``bench.serving.stream_accuracy.train_cached`` of preset ``living-room``: its cameras are the
lounge's), ``demo`` is the shipped demo model (the demo room only).

Per frame: every detected person localized from their own boxes (the true association), error
by posture (frames in a posture transition left out). Streamed: the daemon's chain
(:class:`service.pipeline.chain.Chain`, ``Tracker(**RECOMMENDED)``) on frame timestamps, served
positions matched one-to-one to the people in view (Hungarian, at most ``MATCH_M``): matched
mean error and the share of people in view matched, by posture.

Usage::

    python -m bench.serving.postures [--quick] [--frames 2700]
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import platform
from collections import defaultdict
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from bench.report import command_line
from models.mom.runtime import MomRuntime
from models.simulate import PRESETS, Scene, SceneConfig
from models.simulate.postures import NAMES
from models.simulate.presets import DEMO_FALLS, FACING, fall_route, looping, seated
from service.offline.stream_eval import MIN_VISIBLE_FRACTION, frame_detections, in_view
from service.pipeline.chain import Chain
from service.settings import DEMO_MODEL_DIR
from service.tracking.posture import SITTING, UNKNOWN, camera_postures
from service.tracking.posture_agreement import agreed_rows
from service.tracking.tracker import RECOMMENDED, Tracker

RESULTS = Path(__file__).resolve().parents[1] / "results"
MATCH_M = 1.0
TARGETS = {"sitting": (0.25, 0.20), "lying": (0.40, 0.40)}  # per-frame median, streamed mean


def scenes() -> dict[str, tuple[SceneConfig, str]]:
    """name -> (scene, model: ``usual`` or ``demo``)."""
    lounge = PRESETS["lounge"]
    demo = PRESETS["demo-lounge"]
    falls = fall_route([((2.5, 1.2), 0.0), ((4.2, 2.2), FACING["+y"]), ((1.2, 0.9), 0.0)])
    demo_falls = fall_route(DEMO_FALLS)
    return {
        "lounge": (lounge, "usual"),
        "lounge-falls": (
            dataclasses.replace(lounge, scripts=(seated((2.5, 3.5), "-y"), looping(falls))),
            "usual",
        ),
        "demo-lounge": (demo, "demo"),
        "demo-falls": (
            dataclasses.replace(demo, people=1, scripts=(*demo.scripts, looping(demo_falls))),
            "demo",
        ),
    }


def postures_at(scene: Scene, frame: int) -> np.ndarray:
    """[P] posture name of each labelled person ("transition" while moving between two)."""
    code, weight = scene.walkers.states(frame, frame + 1).postures()
    names = np.array([NAMES[c] for c in code[0]], dtype=object)
    return np.where((weight[0] > 0) & (weight[0] < 1), "transition", names)


@dataclasses.dataclass
class Tally:
    per_frame: dict[str, list[float]] = dataclasses.field(default_factory=lambda: defaultdict(list))
    streamed: dict[str, list[float]] = dataclasses.field(default_factory=lambda: defaultdict(list))
    in_view: dict[str, int] = dataclasses.field(default_factory=lambda: defaultdict(int))
    ids: dict[int, set[int]] = dataclasses.field(default_factory=lambda: defaultdict(set))
    labelled: dict[str, list[bool]] = dataclasses.field(default_factory=lambda: defaultdict(list))
    # seated per frame by what each camera's box reads as alone ("-": unseen)
    seated_views: dict[str, list[float]] = dataclasses.field(
        default_factory=lambda: defaultdict(list)
    )


def run(runtime: MomRuntime, config: SceneConfig, seed: int, frames: int, postures: bool,
        warmup: int = 30) -> Tally:  # fmt: skip
    scene = Scene(config, seed=seed)
    chain = Chain(Tracker(fps_hint=scene.fps, **RECOMMENDED), postures=postures)
    rng = np.random.default_rng([seed, 77])
    delivered = [True] * runtime.num_cameras
    tally = Tally()
    for i in range(frames):
        obs = scene.observe(i)
        _, tracks = chain(i / scene.fps, frame_detections(obs, rng), runtime, delivered, i)
        if i < warmup:
            continue
        posture = postures_at(scene, i)
        seen = np.isfinite(obs.boxes).all(-1).any(-1)
        if seen.any():
            rows = obs.boxes[seen]
            points = obs.keypoints[seen]
            views = box_labels(rows, runtime, points)
            if postures:
                rows = agreed_rows(rows, runtime.setup_area, runtime.image_sizes, points)
            xy = np.asarray(runtime.localize(rows), float)
            errors = np.linalg.norm(xy - obs.world[seen, :2], axis=1)
            for name, err, view in zip(posture[seen], errors, views, strict=True):
                tally.per_frame[name].append(float(err))
                if name == "sitting":
                    tally.seated_views[view].append(float(err))
        want = np.flatnonzero(in_view(obs.true_boxes, scene.image_sizes, MIN_VISIBLE_FRACTION))
        for p in want:
            tally.in_view[posture[p]] += 1
        served = np.array([[t.x, t.y] for t in tracks]).reshape(-1, 2)
        if len(served) and len(want):
            cost = np.linalg.norm(served[:, None] - obs.world[want, None, :2].transpose(1, 0, 2),
                                  axis=2)  # fmt: skip
            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows, cols, strict=True):
                if cost[r, c] <= MATCH_M:
                    person = int(want[c])
                    tally.streamed[posture[person]].append(float(cost[r, c]))
                    tally.ids[person].add(tracks[r].id)
                    served_posture = (tracks[r].posture or (UNKNOWN, 0.0))[0]
                    truth = SITTING if posture[person] == "crouching" else posture[person]
                    tally.labelled[posture[person]].append(served_posture == truth)
    return tally


def box_labels(rows: np.ndarray, runtime: MomRuntime, keypoints: np.ndarray) -> list[str]:
    """Per row of boxes [N, K, 4] (and their keypoints [N, K, 17, 3]): each camera's posture
    of its box alone, e.g. ``sitting + standing`` (``-`` where unseen)."""
    per_camera = [
        camera_postures(rows[:, k], runtime.setup_area, k, runtime.image_sizes[k], keypoints[:, k])[
            0
        ]
        for k in range(rows.shape[1])
    ]
    return [
        " + ".join("-" if not np.isfinite(rows[n, k]).all() else str(per_camera[k][n])
                   for k in range(rows.shape[1]))
        for n in range(len(rows))
    ]  # fmt: skip


def views_table(results: dict[str, Tally]) -> list[str]:
    """Seated per-frame error by what each camera's box reads as alone: where it comes from."""
    lines = ["| scene | cameras' box postures (alone) | per-frame mean m | median m | n |",
             "|---|---|---|---|---|"]  # fmt: skip
    for name, tally in results.items():
        for view, values in sorted(tally.seated_views.items(), key=lambda kv: -len(kv[1])):
            mean, median, n = stats(values)
            lines.append(f"| {name} | {view} | {mean} | {median} | {n} |")
    return lines


def stats(values: list[float]) -> tuple[str, str, str]:
    if not values:
        return "–", "–", "0"
    v = np.array(values)
    return f"{np.mean(v):.3f}", f"{np.median(v):.3f}", str(len(v))


def table(results: dict[str, Tally]) -> list[str]:
    lines = [
        "| scene | posture | per-frame mean m | per-frame median m | n | streamed matched mean m "
        "| streamed median m | served % of in view | served posture right % |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, tally in results.items():
        for posture in (*NAMES, "transition"):
            if not tally.per_frame.get(posture) and not tally.in_view.get(posture):
                continue
            pm, pmed, n = stats(tally.per_frame.get(posture, []))
            sm, smed, sn = stats(tally.streamed.get(posture, []))
            share = 100.0 * int(sn) / max(tally.in_view.get(posture, 0), 1)
            right = tally.labelled.get(posture, [])
            label = f"{100.0 * np.mean(right):.1f}" if right and posture != "transition" else "–"
            lines.append(f"| {name} | {posture} | {pm} | {pmed} | {n} | {sm} | {smed} | "
                         f"{share:.1f} | {label} |")  # fmt: skip
    return lines


def walking_mota(seeds: tuple[int, ...] = (7, 8), frames: int = 600) -> list[str]:
    """The price for walkers: streamed MOTA at 0.5 m and id switches per seed on indoor-2cam
    with 3 people (nanodet profile, the stream bench's model) with and without the posture
    stage (:func:`service.offline.stream_eval.run_stream`, ``postures``)."""
    from bench.serving.stream_accuracy import train_cached
    from service.offline.stream_eval import run_stream, scene_config

    runtime = MomRuntime.load(train_cached("indoor-2cam", None, 3000, 150))
    config = scene_config("indoor-2cam", 3, None)
    rows = ["| postures | walking MOTA % per seed | id switches per seed |", "|---|---|---|"]
    for aware in (False, True):
        runs = [run_stream(runtime, config, seed, frames, postures=aware)[0.5] for seed in seeds]
        mota = ", ".join(f"{r['mota']:.2f}" for r in runs)
        switches = ", ".join(str(r["id_switches"]) for r in runs)
        rows.append(
            f"| {'posture-aware' if aware else 'boxes as detected'} | {mota} | {switches} |"
        )
        print(rows[-1], flush=True)
    return rows


@functools.cache
def usual_model(quick: bool) -> MomRuntime:
    from bench.serving.stream_accuracy import train_cached

    frames, epochs = (800, 40) if quick else (3000, 150)
    return MomRuntime.load(train_cached("living-room", None, frames, epochs))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=2700, help="frames per scene (15 fps)")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--scenes", nargs="*", default=None)
    parser.add_argument("--quick", action="store_true", help="600 frames, small usual model")
    parser.add_argument(
        "--walking",
        action="store_true",
        help="also the walking scenes' MOTA with and without postures (indoor-2cam, 3 people)",
    )
    parser.add_argument("--out", type=Path, default=RESULTS / "postures.md")
    args = parser.parse_args(argv)
    frames = 600 if args.quick else args.frames
    results: dict[str, Tally] = {}
    for name, (config, model) in scenes().items():
        if args.scenes and name not in args.scenes:
            continue
        runtime = usual_model(args.quick) if model == "usual" else MomRuntime.load(DEMO_MODEL_DIR)
        for aware in (False, True):
            key = f"{name}, {model} model, {'posture-aware' if aware else 'boxes as detected'}"
            results[key] = run(runtime, config, args.seed, frames, aware)
            print("\n".join(table({key: results[key]})), flush=True)
    ids = {name: {p: len(s) for p, s in t.ids.items()} for name, t in results.items()}
    text = [
        "# Postures: where people who sit, crouch and lie are put",
        "",
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {platform.node()} ({platform.machine()}), "
        f"`{command_line('bench.serving.postures', argv)}`. {frames} frames per scene at 15 fps, "
        f"seed {args.seed}, nanodet profile. Targets: seated per-frame median ≤ 0.25 m, "
        "streamed matched mean ≤ 0.20 m; lying ≤ 0.40 m.",
        "",
        *table(results),
        "",
        f"Served ids per person (streamed): {ids}",
        "",
        "Where the seated error comes from: per frame (true association), by what each camera's "
        "box reads as alone (`unknown`: at the image border; the posture-aware rows convert "
        "them as one posture per person, `service/tracking/posture_agreement.py`):",
        "",
        *views_table({k: v for k, v in results.items() if v.seated_views}),
        "",
    ]
    if args.walking:
        text += ["Walking (indoor-2cam, 3 people, nanodet profile, seeds 7 8 × 600 frames):", "",
                 *walking_mota(), ""]  # fmt: skip
    args.out.write_text("\n".join(text))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
