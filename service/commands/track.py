"""`momloc track RECORDING_DIR --model MODEL_DIR --out positions.jsonl [--csv]`: the live chain
on recorded data (``service.offline.track``), and with ``--truth`` its served accuracy.

With ``--truth --json`` stdout is exactly one JSON object (the 0.5 m gate's metrics at the top
level, every gate under ``gates``; see ``models.data.stream_metrics``); the progress bar and the
summary line go to stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from common.errors import MomlocError
from service.tracking.smoother import DEFAULT_HALF_WINDOW_S


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "track",
        help="run detection, association, localization and tracking on a recording",
        description="Track people in a 'momloc record' folder (or a dataset file's boxes with "
        "--detections) as fast as the CPU allows; write one snapshot per frame set.",
    )
    parser.add_argument(
        "recording", metavar="RECORDING_DIR", nargs="?", help="folder written by momloc record"
    )
    parser.add_argument(
        "--detections", metavar="DATA.npz", type=Path, default=None,
        help="instead of a recording: a detections replay (momloc import) or a dataset v1 "
        "file's boxes as the detector's output",
    )  # fmt: skip
    parser.add_argument("--model", type=Path, required=True, help="MODEL_DIR (momloc train)")
    parser.add_argument("--out", type=Path, required=True, help="positions file to write")
    parser.add_argument("--csv", action="store_true", help="CSV rows instead of JSON lines")
    parser.add_argument(
        "--truth", metavar="DATA.npz", type=Path, default=None,
        help="dataset v1 file of the same frames: print served-accuracy metrics",
    )  # fmt: skip
    parser.add_argument("--json", action="store_true", help="with --truth: one JSON object")
    parser.add_argument(
        "--config", type=Path, default=None, help="settings file for detector and tracking options"
    )
    parser.add_argument(
        "--fps", type=float, default=None,
        help="with --detections: frame rate of the frame index (default: the replay's own; "
        "15, the simulator's, for a dataset file)",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="seed of the per-camera shuffling")
    parser.add_argument(
        "--smooth-s", type=float, default=DEFAULT_HALF_WINDOW_S, metavar="SECONDS",
        help="fixed-lag smoothing: each position from a straight-line fit over its id's "
        f"positions within +-SECONDS (default {DEFAULT_HALF_WINDOW_S}; 0: as tracked live)",
    )  # fmt: skip
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from models.data.dataset import MomDataset
    from models.mom.runtime import MomRuntime
    from service.offline import track as offline
    from service.offline.track_output import TruthScore, format_scores

    if (args.recording is None) == (args.detections is None):
        raise MomlocError("give either RECORDING_DIR or --detections DATA.npz")
    if args.json and args.truth is None:
        raise MomlocError("--json needs --truth DATA.npz")
    if not args.smooth_s >= 0:
        raise MomlocError(f"--smooth-s {args.smooth_s}: must be 0 (off) or positive seconds")
    runtime = MomRuntime.load(args.model)
    truth = None if args.truth is None else MomDataset.load(args.truth)
    if args.detections is not None:
        feed = offline.detections_feed(args.detections, args.fps, args.seed)
        settings = offline.offline_settings(args.config, [str(args.detections)] * feed.num_cameras)
    else:
        from capture.recording import Recording

        recording = Recording.open(args.recording)
        settings = offline.offline_settings(args.config, [str(c.video) for c in recording.cameras])
        feed = offline.recording_feed(recording, settings)
    pipeline = offline.offline_pipeline(settings, runtime, feed, args.model)
    score = None if truth is None else TruthScore(truth, feed.num_cameras, feed.total)
    summary = offline.run_track(
        pipeline, feed, args.out, as_csv=args.csv, score=score, smooth_s=args.smooth_s
    )
    print(
        f"{args.out}: {summary.frame_sets} frame sets in {summary.seconds:.1f} s "
        f"({summary.rate:.1f} sets/s), {summary.positions} positions, {summary.ids} ids",
        file=sys.stderr,
    )
    if score is not None:
        result = score.result()
        print(json.dumps(result, allow_nan=False) if args.json else format_scores(result))
    return 0
