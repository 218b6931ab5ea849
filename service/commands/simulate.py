"""`momloc simulate`: write a synthetic multi-camera recording as a MoM dataset v1 file (and with
``--record DIR`` its drawn frames as a ``momloc record`` folder, ``service.offline.record``)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from common.errors import MomlocError

if TYPE_CHECKING:  # the simulator loads when the command runs: `momloc --help` stays fast
    from models.simulate import Perturbation


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
        help="scene preset (indoor-2cam, indoor-4cam, outdoor-6cam, living-room, office-3cam, "
        "single-cam); default indoor-2cam",
    )
    parser.add_argument("--frames", type=int, default=2000, help="number of frames (default 2000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--profile",
        default=None,
        metavar="NAME",
        help="detector profile: how blind the simulated detector is; nanodet (default, the "
        "shipped detector), ssdlite, ideal (the former kind noise), or a profile JSON path",
    )
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
    parser.add_argument(
        "--room",
        default=None,
        metavar="WxD",
        help="room size in metres, e.g. 6x4 (default: the preset's)",
    )
    parser.add_argument(
        "--cameras", type=int, default=None, metavar="K",
        help="number of cameras, 1-9, hung corners first (default: the preset's)",
    )  # fmt: skip
    parser.add_argument(
        "--bump", action="append", default=[], metavar="CAM,FRAME,DX,DY[,ROLL]",
        help="camera CAM is bumped at FRAME: image shifted by DX, DY pixels and rolled by ROLL "
        "degrees (repeatable)",
    )  # fmt: skip
    parser.add_argument(
        "--record", default=None, metavar="DIR",
        help="also draw every camera's frames into a recording folder (momloc record format), "
        "frame set i = dataset frame i, for momloc track --truth",
    )  # fmt: skip
    parser.set_defaults(func=run)


def _room(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        width, depth = (float(part) for part in text.lower().split("x"))
    except ValueError:
        raise MomlocError(f"--room '{text}': expected WIDTHxDEPTH in metres, e.g. 6x4") from None
    return width, depth


def _bumps(texts: list[str]) -> list[Perturbation] | None:
    from models.simulate import Perturbation

    out = []
    for text in texts:
        try:
            parts = [float(p) for p in text.split(",")]
            if len(parts) not in (4, 5) or parts[0] != int(parts[0]) or parts[1] != int(parts[1]):
                raise ValueError
        except ValueError:
            raise MomlocError(
                f"--bump '{text}': expected CAM,FRAME,DX,DY[,ROLL] (integers CAM and FRAME)"
            ) from None
        roll = parts[4] if len(parts) == 5 else 0.0
        out.append(Perturbation(int(parts[0]), int(parts[1]), parts[2], parts[3], roll))
    return out or None


def run(args: argparse.Namespace) -> int:
    from capture.recording import check_new_folder
    from models.simulate import simulate

    if args.record is not None:
        check_new_folder(args.record)  # before minutes of simulation, not after
    result = simulate(
        args.preset, args.frames, seed=args.seed, people=args.people, fps=args.fps,
        perturbation=_bumps(args.bump), room=_room(args.room), cameras=args.cameras,
        detector_profile=args.profile,
    )  # fmt: skip
    path = result.dataset.save(args.out)
    print(f"{path}: {result.dataset.summary()}")
    if args.record is not None:
        from service.offline.record import record_scene

        print(record_scene(result.scene, args.frames, args.record).line())
    return 0
