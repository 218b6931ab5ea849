"""`momloc import --mot CAM.txt... --image-size WxH... --replay OUT.npz [--positions POS.txt
--dataset OUT.npz]`: your own detections (MOTChallenge text, one file per camera) as a
detections replay for ``momloc track --detections``, and with a positions file as a MoM dataset
v1 for ``momloc train`` / ``--truth`` (formats: ``models.data.mot_import``)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "import",
        help="import per-camera MOTChallenge detections (+ positions) as replay / dataset",
        description="Read one MOTChallenge detection file per camera (frame, id, bb_left, "
        "bb_top, bb_width, bb_height, conf, ...), in camera order. Write every box as a "
        "detections replay (--replay) and, when the rows carry ids and a positions file "
        "(frame, id, x, y in metres) is given, a MoM dataset v1 (--dataset).",
    )
    parser.add_argument(
        "--mot", nargs="+", required=True, type=Path, metavar="CAM.txt",
        help="one MOTChallenge file per camera, in camera order",
    )  # fmt: skip
    parser.add_argument(
        "--image-size", nargs="+", required=True, metavar="WxH",
        help="image size of every camera (one value) or of each camera in order",
    )  # fmt: skip
    parser.add_argument("--fps", type=float, required=True, help="frame rate of the frame index")
    parser.add_argument(
        "--replay", type=Path, default=None, metavar="OUT.npz",
        help="write the detections replay (momloc detections v1)",
    )  # fmt: skip
    parser.add_argument(
        "--positions", type=Path, default=None, metavar="POS.txt",
        help="true floor positions: frame, id, x, y (metres)",
    )  # fmt: skip
    parser.add_argument(
        "--dataset", type=Path, default=None, metavar="OUT.npz",
        help="write a MoM dataset v1 (needs --positions and ids in the MOT rows)",
    )  # fmt: skip
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from common.errors import MomlocError
    from models.data.mot_import import (
        build_dataset,
        build_replay,
        parse_size,
        read_mot,
        read_positions,
    )

    if args.replay is None and args.dataset is None:
        raise MomlocError("nothing to write: give --replay and/or --dataset")
    if (args.dataset is None) != (args.positions is None):
        raise MomlocError("--dataset and --positions go together")
    if not args.fps > 0:
        raise MomlocError(f"--fps {args.fps:g}: must be positive")
    sizes = [parse_size(s) for s in args.image_size]
    if len(sizes) == 1:
        sizes = sizes * len(args.mot)
    if len(sizes) != len(args.mot):
        raise MomlocError(
            f"--image-size: {len(sizes)} sizes for {len(args.mot)} cameras (give one or one each)"
        )
    cameras = [read_mot(path) for path in args.mot]
    if args.replay is not None:
        replay = build_replay(cameras, sizes, args.fps)
        replay.save(args.replay)
        frames = len(set(replay.frame.tolist()))
        print(f"{args.replay}: {replay.n} boxes, {frames} frames, {replay.num_cameras} cameras")
    if args.dataset is not None:
        data = build_dataset(cameras, read_positions(args.positions), sizes, args.mot)
        data.save(args.dataset)
        print(f"{args.dataset}: {data.summary()}")
    return 0
