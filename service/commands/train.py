"""`momloc train DATA.npz --out MODEL_DIR`: fit a MoM model and write encoder.onnx + model.json.

Torch is imported inside :func:`run` only, so the serving commands never load it.
"""

from __future__ import annotations

import argparse
import json
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "train",
        help="train a MoM model from a dataset file",
        description="Train the MoM encoder (+ decoder) on a MoM dataset v1 file. Sizes, schedule "
        "and early stopping adapt to the data; the progress bar shows the validation error.",
    )
    parser.add_argument("data", metavar="DATA.npz", help="MoM dataset v1 file")
    parser.add_argument("--out", required=True, metavar="MODEL_DIR", help="output directory")
    parser.add_argument(
        "--observation",
        choices=("bbox", "keypoints"),
        default="bbox",
        help="what the mean estimators are built from (default: bbox)",
    )
    parser.add_argument(
        "--no-decoder",
        dest="decoder",
        action="store_false",
        help="train without the decoder's reprojection loss (λ = 0)",
    )
    parser.add_argument(
        "--epochs", type=int, default=None, help="maximum epochs (default: adaptive)"
    )
    parser.add_argument(
        "--time-budget",
        type=float,
        default=None,
        metavar="SECONDS",
        help="stop after this many seconds of training, keeping the best epoch so far "
        "(default: the adaptive schedule's safety net, 540 s; none with --epochs)",
    )
    parser.add_argument(
        "--policy",
        choices=("auto", "prior"),
        default="auto",
        help="which localizer the model serves: auto (chosen from the rows: floor-mark geometry "
        "for marks, a validated blend for dense walks) or prior (the floor geometry fitted on all "
        "rows, for rows whose positions a model produced, such as the room's self-labels)",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument(
        "--progress-json",
        action="store_true",
        help='one JSON line per epoch on stdout: {"epoch", "max_epochs", "val_error_m" (mean), '
        '"val_median_m"} (for programs following the training, e.g. the /setup page)',
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from common.errors import MomlocError
    from models.data.dataset import MomDataset
    from models.mom.training.train import train_model

    if args.time_budget is not None and not args.time_budget > 0:
        raise MomlocError(f"--time-budget {args.time_budget:g}: must be positive seconds")
    data = MomDataset.load(args.data)
    if not args.quiet:
        print(f"momloc train: {args.data}: {data.summary()}")
    metrics = train_model(
        data,
        args.out,
        observation=args.observation,
        decoder=args.decoder,
        epochs=args.epochs,
        seed=args.seed,
        progress=not args.quiet,
        tuning=None if args.time_budget is None else {"time_budget_s": args.time_budget},
        on_epoch=_print_epoch if args.progress_json else None,
        policy=args.policy,
    )
    summary = {k: v for k, v in metrics.items() if k != "val_history"}
    print(json.dumps(summary))
    if metrics["floor_prior"]["policy"] == "prior" and args.policy == "auto":
        print(
            f"note: the validation rows sit on the same floor marks as the training rows, so "
            f"{metrics['val_mean_m']:.3f} m says nothing about the floor between them; the model "
            f"serves floor-mark geometry there. To measure it, record a walk over the room and "
            f"run `momloc eval {args.out} WALK.npz`.",
            file=sys.stderr,
        )
    return 0


def _print_epoch(epoch: int, max_epochs: int, val_error_m: float, val_median_m: float) -> None:
    line = {
        "epoch": epoch,
        "max_epochs": max_epochs,
        "val_error_m": round(val_error_m, 4),
        "val_median_m": round(val_median_m, 4),
    }
    print(json.dumps(line), flush=True)
