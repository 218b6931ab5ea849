"""`momloc record --config FILE --out DIR [--seconds S]`: record every camera's frames with their
capture times, as the pipeline would fuse them (format: :mod:`capture.recording`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from common.errors import MomlocError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "record",
        help="record the cameras' frames and capture times for replay and offline tracking",
        description="Record the cameras of a settings file as frame sets (MJPG .avi and a "
        "timestamps file per camera, a manifest) into a new folder. Replay it with "
        "'type: file' cameras, track it with 'momloc track'.",
    )
    parser.add_argument("--config", type=Path, required=True, help="settings file (YAML)")
    parser.add_argument("--out", type=Path, required=True, help="new (or empty) folder")
    parser.add_argument(
        "--seconds", type=float, default=None, help="stop after this long (default: Ctrl-C)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from service.offline.record import record_live
    from service.settings import load_settings

    if args.seconds is not None and not args.seconds > 0:
        raise MomlocError(f"--seconds {args.seconds:g}: must be positive")
    settings = load_settings(args.config)
    print(record_live(settings, args.out, args.seconds).line())
    return 0
