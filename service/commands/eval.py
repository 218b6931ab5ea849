"""`momloc eval MODEL_DIR DATA.npz [--json]`: accuracy of a trained model on a dataset file.

Prints a readable table, or with ``--json`` exactly one JSON object on stdout whose keys are
``n, mean, median, std, ate, rpe, acc@0.2, acc@0.3, acc@0.4, acc@0.5`` (metres, percent; an
undefined RPE is ``null``). Metric definitions: :mod:`models.metrics`. Notes (skipped rows) go to
stderr so stdout stays machine-readable.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from models.errors import MomlocError


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
    parser.set_defaults(func=run)


def _json_value(value: float) -> float | int | None:
    return None if isinstance(value, float) and math.isnan(value) else value


def run(args: argparse.Namespace) -> int:
    from models.dataset import MomDataset
    from models.evaluate import evaluate
    from models.metrics import format_table
    from models.mom_runtime import MomRuntime

    model_dir = Path(args.model_dir)
    if not model_dir.is_dir():
        raise MomlocError(f"model directory {model_dir}: not found")
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
