"""A bumped camera that repairs itself, measured (writes bench/results/self_healing.md).

``python -m bench.setup.self_healing [--quick]``

Protocol: indoor-2cam, detector ``--profile`` (nanodet); a model set up on 9 floor marks
(3 × 3, the set-up plan) serves 3 people walking; ``--bump-s`` seconds in, camera 1 is bumped
(roll 3°, shift 10 px: :class:`models.simulate.Perturbation`). The daemon's listeners run on
every frame set (:class:`bench.setup.room_run.RoomRun`): the camera-moved checks (the image
check on frames drawn once a second, the reprojection check) and the learning room with its
self-healing job (:class:`service.learning.healer.Healer`), which swaps the repaired model in as
``Pipeline.reload_model`` would. Reported: scene time from the bump to the alert and to the
repaired model in service, and the per-frame error on a dense test room (people localized
from their true boxes, other seed) before the bump, after it, and after the repair.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path
from typing import Any

from bench.report import RESULTS, machine_line, markdown_table
from bench.setup.room_run import RoomRun
from bench.setup.self_learning import TEST_SEED, train
from bench.setup.setup_stream import collect_marks
from models.mom.evaluate import evaluate
from models.mom.runtime import MomRuntime
from models.simulate import Perturbation, simulate
from service.learning.healer import MIN_POSITIONS, Healer
from service.offline.stream_eval import scene_config
from service.stages import LocalizationModel

CAMERA = 1


def bump(start_frame: int) -> Perturbation:
    return Perturbation(camera=CAMERA, start_frame=start_frame, dx=10.0, roll_deg=3.0)


def heal_run(
    seed: int,
    model_dir: Path,
    work: Path,
    profile: str,
    bump_s: float,
    max_s: float,
    min_positions: int = MIN_POSITIONS,
    preset: str = "indoor-2cam",
) -> dict[str, Any]:
    config = scene_config(preset, 3, profile)
    fps = config.fps
    config = dataclasses.replace(config, perturbations=(bump(int(bump_s * fps)),))
    data_dir = work / f"heal-{seed}"
    runtime = MomRuntime.load(model_dir)
    room = RoomRun(config, seed, runtime, data_dir, watch=True)
    healer = Healer(data_dir, room.labeler, room, min_positions=min_positions)
    room.labeler.followers.append(healer)
    alert = repaired = None
    while room.frame < int(max_s * fps):
        room.step()
        t = room.frame / fps
        if alert is None and t >= bump_s and room.moved():
            alert = t - bump_s
        if repaired is None and any(s.state == "repaired" for s in healer.done):
            repaired = t - bump_s
            break
    return {
        "seed": seed,
        "alert_s": alert,
        "repaired_s": repaired,
        "status": healer.status(),
        "model": room.runtime,
        "moved": sorted(room.moved()),
    }


def per_frame(model: LocalizationModel, data: Any) -> float:
    return float(evaluate(model, data).metrics["mean"])  # type: ignore[arg-type]


def run(args: argparse.Namespace) -> Path:
    seeds = args.seeds[:1] if args.quick else args.seeds
    frames = 300 if args.quick else 900
    preset = args.preset
    before = simulate(preset, frames, TEST_SEED, detector_profile=args.profile).dataset
    after = simulate(
        preset, frames, TEST_SEED, detector_profile=args.profile, perturbation=bump(0)
    ).dataset
    rows: list[tuple[Any, ...]] = []
    name = "self_healing_quick.md" if args.quick else "self_healing.md"
    path = args.out or RESULTS / name

    def save() -> None:
        table = markdown_table(
            ("seed", "alert after s", "repaired after s", "error before bump m", "after bump m",
             "repaired m", "repaired / before", "what health says"),
            rows,
        )  # fmt: skip
        path.write_text(
            "# The room that learns: a bumped camera repairs itself\n\n"
            f"{machine_line()}\n\n"
            f"{preset}, detector profile `{args.profile}`, a model set up on 9 floor marks × "
            f"{args.seconds:g} s; 3 people walk; camera {CAMERA} bumped (roll 3°, shift 10 px) "
            f"{args.bump_s:g} s into the run (scene time); repaired from {args.positions} "
            "positions (`learning.heal_min_positions`). Times are scene seconds after the bump; "
            f"errors are per-frame means on a dense test room ({before.n} person instances, seed "
            f"{TEST_SEED}) seen by the unbumped and by the bumped cameras. The repair fits the "
            "bump as one image transform of the former model (the camera's image rolled and "
            "shifted, `service/learning/bump.py`) to the positions the other cameras give (with "
            "two cameras: the other camera's single views, weighted by their covariances), and "
            "refits the camera's maps only when no transform explains them "
            "(`service/learning/heal.py`). "
            f"Command: `python -m bench.setup.self_healing --preset {preset} --seeds "
            f"{' '.join(map(str, seeds))} --positions {args.positions}`. "
            "Code: `bench/setup/self_healing.py`.\n\n"
            f"{table}\n"
        )

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        marks = collect_marks("3x3", args.seconds, args.profile, work / "marks9.npz", preset)
        start = train(marks, work / "model")
        e_before, e_bumped = per_frame(start, before), per_frame(start, after)
        for seed in seeds:
            got = heal_run(
                seed, work / "model", work, args.profile, args.bump_s, args.max_s,
                args.positions, preset,
            )  # fmt: skip
            repaired = got["model"] if got["repaired_s"] is not None else None
            e_repaired = None if repaired is None else per_frame(repaired, after)
            message = got["status"][-1]["message"] if got["status"] else "no repair started"
            print(seed, got["alert_s"], got["repaired_s"], e_repaired, message, flush=True)
            rows.append(
                (
                    seed,
                    _s(got["alert_s"]),
                    _s(got["repaired_s"]),
                    f"{e_before:.3f}",
                    f"{e_bumped:.3f}",
                    "–" if e_repaired is None else f"{e_repaired:.3f}",
                    "–" if e_repaired is None else f"{e_repaired / e_before:.2f}×",
                    message,
                )
            )
            save()
    return path


def _s(value: float | None) -> str:
    return "–" if value is None else f"{value:.0f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed")
    parser.add_argument("--profile", default="nanodet")
    parser.add_argument("--preset", default="indoor-2cam", help="indoor-2cam or indoor-4cam")
    parser.add_argument("--seconds", type=float, default=20.0, help="per floor mark")
    parser.add_argument("--bump-s", type=float, default=60.0)
    parser.add_argument("--max-s", type=float, default=300.0, help="give up after this long")
    parser.add_argument("--seeds", type=int, nargs="+", default=[31, 32])
    parser.add_argument(
        "--positions", type=int, default=MIN_POSITIONS, help="learning.heal_min_positions"
    )
    parser.add_argument("--out", type=Path, default=None, help="results file")
    print(run(parser.parse_args()))


if __name__ == "__main__":
    main()
