"""`momloc simulate`: write a synthetic multi-camera recording as a MoM dataset v1 file."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="simulate a multi-camera scene and write a dataset .npz",
        description="Simulate people walking in a room seen by K webcams (detector-like noisy "
        "boxes and keypoints) and write a MoM dataset v1 file.",
    )
    parser.add_argument(
        "--preset",
        default="indoor-2cam",
        help="scene preset (indoor-2cam, indoor-4cam, outdoor-6cam, living-room, "
        "office-3cam, single-cam); default indoor-2cam",
    )
    parser.add_argument("--frames", type=int, default=2000, help="number of frames (default 2000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--out", required=True, help="output .npz file")
    parser.add_argument(
        "--people", type=int, default=None, help="number of people (default: the preset's)"
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        help="frame rate of the scene (default: the preset's, 15)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from models.simulate import simulate

    result = simulate(args.preset, args.frames, seed=args.seed, people=args.people, fps=args.fps)
    path = result.dataset.save(args.out)
    print(f"{path}: {result.dataset.summary()}")
    return 0
