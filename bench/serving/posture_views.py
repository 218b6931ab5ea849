"""How far apart two cameras put a person seen compact, read seated and read lying (writes
bench/results/posture_views.md): the evidence for :mod:`service.tracking.posture_views`.

The simulated lounge (the fall bench's room and model, ``bench.serving.falls``), nanodet
profile, the true association: every person both cameras detect with boxes that read sitting
or lying by their shape. Each box is localized alone twice, converted as a seated head (from
its top) and as a body on the floor (:data:`~service.tracking.posture.LYING_FOOT` down it), and
the distance between the two cameras' seated readings and between their lying readings is
tallied by the posture the person holds (from the top of their body over their height: lying
below 0.22, crouching 0.3-0.6, sitting 0.6-0.8). Scenes: fall scenes of seeds 1-12 (10 fps,
every other frame) and three 20-minute stretches of daily life (5 fps, every other frame),
none of the fall bench's seeds.

Usage::

    python -m bench.serving.posture_views [--fall-seeds 12] [--daily-minutes 20]
"""

from __future__ import annotations

import argparse
import platform
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from bench.report import command_line
from bench.serving import falls as fb
from models.mom.runtime import MomRuntime
from models.simulate import Scene
from service.tracking.posture import LYING, SITTING, box_postures, standing_boxes
from service.tracking.posture_views import AGREE_M, APART_M

RESULTS = Path(__file__).resolve().parents[1] / "results"
HELD = {  # the posture a person holds, by the top of their body over their height
    "lying": (0.0, 0.22),
    "crouching": (0.3, 0.6),
    "sitting": (0.6, 0.8),
}


def spreads(runtime: MomRuntime, scene: Scene, frames: int, step: int) -> np.ndarray:
    """Rows [N, 4] of (top over height, seated readings apart m, lying readings apart m, some
    box reads lying) for each person both cameras see compact, every ``step``-th frame."""
    area = runtime.setup_area
    heights = scene.walkers.heights
    rows = []
    for i in range(0, frames, step):
        seen = scene.observe(i)
        for person in range(len(seen.track)):
            boxes = seen.boxes[person]
            if len(boxes) != 2 or not np.isfinite(boxes).all():
                continue
            labels = [
                str(box_postures(boxes[k][None], area, k, runtime.image_sizes[k])[0][0])
                for k in range(2)
            ]
            if any(label not in (SITTING, LYING) for label in labels):
                continue
            alone = np.full((4, 2, 4), np.nan)
            for k in range(2):
                for n, label in enumerate((SITTING, LYING)):
                    kind = np.array([label], dtype=object)
                    alone[2 * n + k, k] = standing_boxes(boxes[k][None], kind, area, k)[0]
            world = np.asarray(runtime.localize(alone), np.float64)[:, :2]
            top = float(seen.joints[person, :, 2].max() / heights[person])
            seated, lying = (float(np.linalg.norm(world[n] - world[n + 1])) for n in (0, 2))
            rows.append((top, seated, lying, float(LYING in labels)))
    return np.array(rows, dtype=np.float64).reshape(-1, 4)


def table(falls: np.ndarray, daily: np.ndarray) -> list[str]:
    """The spreads by held posture, and what the rule takes of each."""
    out = [
        "| held posture | scenes | frames | seated readings apart, 5 / 50 / 95 % "
        "| lying readings apart, 5 / 50 / 95 % | read lying by the views | of those no box "
        "read lying |",
        "|:--|:--|--:|--:|--:|--:|--:|",
    ]
    for name, scenes, rows in (
        ("lying", "falls", falls),
        ("crouching", "daily life", daily),
        ("sitting", "both", np.concatenate([falls, daily])),
    ):
        low, high = HELD[name]
        held = rows[(rows[:, 0] >= low) & (rows[:, 0] < high)]
        if not len(held):
            continue
        taken = (held[:, 2] <= AGREE_M) & (held[:, 1] >= APART_M)
        none_lying = held[:, 3] == 0
        quantiles = [
            " / ".join(f"{v:.2f}" for v in np.percentile(held[:, c], [5, 50, 95])) + " m"
            for c in (1, 2)
        ]
        out.append(
            f"| {name} | {scenes} | {len(held)} | {quantiles[0]} | {quantiles[1]} "
            f"| {taken.mean():.1%} | {int(taken[none_lying].sum())} of {int(none_lying.sum())} |"
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fall-seeds", type=int, default=12)
    parser.add_argument("--daily-minutes", type=float, default=20.0)
    parser.add_argument("--out", type=Path, default=RESULTS / "posture_views.md")
    args = parser.parse_args(argv)
    runtime = fb.room_model("lounge")
    assert isinstance(runtime, MomRuntime)
    room = fb.ROOMS["lounge"]
    scenes = [fb.fall_scene(room, seed, 10.0) for seed in range(1, args.fall_seeds + 1)]
    falls = np.concatenate([spreads(runtime, scene, frames, 2) for scene, _, frames in scenes])
    seconds = args.daily_minutes * 60.0
    daily = np.concatenate(
        [
            spreads(runtime, fb.daily_scene(room, seed, 0, seconds, 5.0), int(seconds * 5.0), 2)
            for seed in (1, 2, 3)
        ]
    )
    text = [
        "# Two views of a compact person: seated and lying readings",
        "",
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {platform.node()} ({platform.machine()}), "
        f"`{command_line('bench.serving.posture_views', argv)}`. The rule "
        f"(`service/tracking/posture_views.py`): lying readings within {AGREE_M} m, seated "
        f"readings {APART_M} m apart or more. Two-view compact frames of daily life: "
        f"{len(daily)}, read lying by the views: "
        f"{int(((daily[:, 2] <= AGREE_M) & (daily[:, 1] >= APART_M)).sum())}.",
        "",
        *table(falls, daily),
        "",
    ]
    args.out.write_text("\n".join(text))
    print("\n".join(text))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
