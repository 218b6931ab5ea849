"""`momloc eval MODEL_DIR DATA.npz [--json] [--served]`: accuracy of a trained model on a
dataset file.

Prints a readable table, or with ``--json`` exactly one JSON object on stdout whose keys are
``n, mean, median, std, ate, rpe, acc@0.2, acc@0.3, acc@0.4, acc@0.5`` (metres, percent; an
undefined RPE is ``null``). Metric definitions: :mod:`models.data.metrics`. Notes (skipped rows) go
to stderr so stdout stays machine-readable.

``--served`` scores a floor-mark recording as the set-up page's check step does: what the
daemon serves (association and tracking, :mod:`service.offline.served_marks`), the nearest served
person per frame, the median per mark and over marks. With ``--json`` the object is the check's
summary (``median_m, mean_m, marks, unmeasured, per_mark, text``; each mark ``name, x, y, error_m,
samples, rows``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from common.errors import MomlocError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "eval",
        help="localization metrics of a trained model on a dataset file",
        description="Localize every row of DATA.npz with the model in MODEL_DIR and report mean, "
        "median, std error, ATE, RPE and Acc@0.2/0.3/0.4/0.5 m.",
    )
    parser.add_argument("model_dir", metavar="MODEL_DIR", help="directory written by momloc train")
    parser.add_argument("data", metavar="DATA.npz", help="MoM dataset v1 file with ground truth")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument(
        "--served", action="store_true",
        help="score a floor-mark recording as the set-up check does: the positions the daemon "
        "serves (association + tracking), median error per mark and over marks",
    )  # fmt: skip
    parser.add_argument(
        "--fps", type=float, default=15.0,
        help="with --served: frame rate of the dataset's frame index (default 15)",
    )  # fmt: skip
    parser.set_defaults(func=run)


def _json_value(value: float) -> float | int | None:
    return None if isinstance(value, float) and math.isnan(value) else value


def run(args: argparse.Namespace) -> int:
    from models.data.dataset import MomDataset
    from models.data.metrics import format_table
    from models.mom.evaluate import evaluate
    from models.mom.runtime import MomRuntime

    model_dir = Path(args.model_dir)
    if not model_dir.is_dir():
        raise MomlocError(f"model directory {model_dir}: not found")
    if args.served:
        return _run_served(model_dir, Path(args.data), args.fps, args.json)
    runtime = MomRuntime.load(model_dir)
    data = MomDataset.load(args.data)
    result = evaluate(runtime, data, name=str(args.data))
    if result.skipped:
        print(f"note: {result.skipped} row(s) seen by no camera were not scored", file=sys.stderr)
    if args.json:
        payload = {key: _json_value(value) for key, value in result.metrics.items()}
        print(json.dumps(payload, allow_nan=False))
    else:
        print(f"{args.data}: {data.summary()}")
        weights = ", ".join(f"{w:g}" for w in runtime.prior_weights)
        print(
            f"model: {model_dir} ({runtime.observation}, {runtime.num_cameras} cameras; "
            f"localizer {runtime.policy}, floor-prior weight per 1/2/3+ views: {weights})"
        )
        print(format_table(result.metrics))
    return 0


def _run_served(model_dir: Path, data: Path, fps: float, as_json: bool) -> int:
    from service.offline.served_marks import served_at_marks

    summary = served_at_marks(model_dir, data, fps=fps)
    if as_json:
        print(json.dumps(summary, allow_nan=False))
        return 0
    print(f"{data}: served at {len(summary['per_mark'])} marks, {summary['text']}")
    for mark in summary["per_mark"]:
        error = "nobody served" if mark["error_m"] is None else f"{mark['error_m']:.3f} m"
        print(
            f"  {mark['name']:>8} ({mark['x']:.2f}, {mark['y']:.2f}): {error} "
            f"({mark['samples']} of {mark['rows']} frames)"
        )
    return 0
