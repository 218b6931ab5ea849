"""``momloc collect``: guided recording at floor marks, written as dataset v1 (nothing lost)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the command's modules load when it runs: `momloc --help` stays fast
    from service.setup.collector import Progress
    from service.setup.feeds import LiveFeed, SyntheticFeed


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "collect",
        help="record detections while a person stands on floor marks (calibration-free setup)",
        description="For each floor mark: go there, a countdown, then hold still (swaying and "
        "turning) while detections from all cameras are recorded. Appends to --out atomically; "
        "re-running resumes and skips marks already recorded.",
    )
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--marks", help="YAML marks file (name, x, y in metres)")
    where.add_argument("--grid", help="a regular grid of marks, RxC (e.g. 3x3); needs --room")
    parser.add_argument("--room", help="room size WxD in metres for --grid (synthetic: preset's)")
    parser.add_argument(
        "--source",
        choices=("cameras", "synthetic"),
        default="cameras",
        help="live cameras from --config, or the synthetic scene with a simulated person",
    )
    parser.add_argument("--config", help="daemon settings file (cameras, detector) for live mode")
    parser.add_argument("--preset", default="indoor-2cam", help="synthetic scene preset")
    parser.add_argument("--seed", type=int, default=0, help="synthetic scene seed")
    parser.add_argument(
        "--profile",
        default=None,
        metavar="NAME",
        help="synthetic: simulated detector profile (nanodet default, ssdlite, ideal, or a path)",
    )
    parser.add_argument("--seconds", type=float, required=True, help="seconds recorded per mark")
    parser.add_argument("--out", required=True, help="dataset file to create or extend (.npz)")
    parser.add_argument("--walk", action="store_true", help="also record the walks between marks")
    parser.add_argument("--countdown", type=float, default=3.0, help="seconds before recording")
    parser.add_argument("--move-seconds", type=float, default=5.0, help="time to reach a mark")
    parser.add_argument("--redo", action="store_true", help="record marks already in --out again")
    parser.add_argument(
        "--require-all-cameras",
        action="store_true",
        help="keep only frames where every camera sees the person",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from tqdm import tqdm

    from common.errors import MomlocError
    from service.setup.collector import DatasetAppender, collect, plan_steps
    from service.setup.marks import grid_marks, load_marks

    if args.source == "synthetic":
        from models.simulate import get_config

        room = get_config(args.preset).room
        room_text = args.room or f"{room[0]}x{room[1]}"
    else:
        room_text = args.room
    if args.grid and not room_text:
        raise MomlocError("--grid needs --room WxD (metres)")
    marks = load_marks(args.marks) if args.marks else grid_marks(args.grid, room_text)

    feed = _open_feed(args)
    try:
        writer = DatasetAppender(Path(args.out), feed.image_sizes)
    except MomlocError:
        feed.close()
        raise
    todo = [m for m in marks if args.redo or not writer.has_mark(m)]
    incomplete = [m.name for m in todo if not args.redo and writer.has_rows_at(m)]
    if incomplete:
        print(f"recording again, interrupted before: {', '.join(incomplete)}")
    if not todo:
        feed.close()
        print(f"all {len(marks)} marks are already in {args.out}; use --redo to record again")
        return 0
    from service.setup.feeds import SyntheticFeed

    start = _room_centre(feed) if isinstance(feed, SyntheticFeed) else (todo[0].x, todo[0].y)
    steps = plan_steps(
        todo,
        args.seconds,
        start=start,
        walk=args.walk,
        move_s=args.move_seconds,
        countdown_s=args.countdown,
    )
    feed.prepare(steps)
    begins = [0.0]
    for step in steps:  # running sum: progress per frame must not cost O(steps)
        begins.append(begins[-1] + step.seconds)
    total = begins[-1]
    bar = tqdm(total=round(total, 1), unit="s", desc="collect", mininterval=0.5)
    shown = {"step": -1}

    def on_progress(progress: Progress) -> None:
        if progress.step_index != shown["step"]:
            shown["step"] = progress.step_index
            tqdm.write(f"[{progress.step_index + 1}/{progress.steps}] {progress.step.instruction}")
        done = begins[progress.step_index]
        bar.n = round(min(done + progress.fraction * progress.step.seconds, total), 1)
        seen = " ".join(
            f"cam{k}:{'-' if n == 0 else 'ok' if n == 1 else f'{n} people!'}"
            for k, n in enumerate(progress.cameras_seeing)
        )
        bar.set_postfix_str(f"{seen} kept={progress.kept_rows}", refresh=False)
        bar.update(0)  # redraws at most every `mininterval`

    try:
        collect(
            feed,
            steps,
            writer,
            require_all_cameras=args.require_all_cameras,
            on_progress=on_progress,
        )
    finally:
        feed.close()
        bar.close()
        kept = writer.existing_rows + writer.new_rows
        print(f"{args.out}: {writer.new_rows} new rows, {kept} in total")
    return 0


def _room_centre(feed: SyntheticFeed) -> tuple[float, float]:
    return (feed.room[0] / 2, feed.room[1] / 2)


def _open_feed(args: argparse.Namespace) -> SyntheticFeed | LiveFeed:
    from common.errors import MomlocError
    from service.setup.feeds import LiveFeed, SyntheticFeed

    if args.source == "synthetic":
        return SyntheticFeed(args.preset, args.seed, detector_profile=args.profile)
    if not args.config:
        raise MomlocError("live collection needs --config FILE (cameras and detector)")
    return LiveFeed.from_config(args.config)
