"""`make bench-real-learning`: the real CMC room teaches itself and heals a bumped camera.

Issue 26, 4(c). Data: Ong, Vo, Vo, Kim, Nordholm, TPAMI 2020 (``../shared/data/cmc``; evaluation
only, read from ``--data``, never copied); real Faster R-CNN boxes, 4 cameras, 4 fps.

**Self-improvement.** A model set up on a few marks' worth of CMC1 rows (``marks4`` / ``marks9``
of :mod:`bench.real.cmc_setup`: the labelled rows within 0.3 m of a 2 x 2 / 3 x 3 grid of
marks) serves CMC1's and then CMC2's raw boxes (every box of every camera, one after the other,
:func:`bench.real.cmc_learning_run.chained`) through the daemon's pipeline with its self-label
collector (:mod:`bench.real.cmc_learning_run`); then one self-improvement run
(:class:`service.learning.improve.Improver`: the real ``momloc train`` child on the marks plus
the self-labels, and the never-worse gate, as they are on main) decides whether its candidate
replaces the model. Every model is scored on CMC2 (10 people): per frame with the true
association (every person's real boxes localized, ``momloc eval``'s mean), and end to end through
the chain (``bench.real.cmc.evaluate``: MODA, matched mean, streamed MOTA), against the model
trained on every labelled CMC1 row (``dense``). The candidate learned from CMC2's boxes (not its
truth): the room is scored on the people it learned from, as a running room would be.

**Self-healing.** The ``marks9`` model serves CMC1, then CMC2 and CMC1 again with camera
:data:`CAMERA`'s boxes bumped (:mod:`bench.real.cmc_bump`: roll 3°, shift 10 px, a homography of
the image); the healer repairs it from the positions the other cameras give. Errors before the
bump, after it and after the repair: per frame on CMC2 (all cameras; and the bumped camera
alone, its single views) and end to end.

Figures: ``bench/results/self_learning_cmc.md`` (and ``.json``).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.real import cmc_data
from bench.real.cmc import DEFAULT_DATA, evaluate
from bench.real.cmc_bump import bump_homography, bumped_dataset, bumped_replay
from bench.real.cmc_chain import Ground, score, serve
from bench.real.cmc_learning_run import chained, serve_learning
from bench.real.cmc_setup import labelled_dataset, replay_path, trained_model, variant_rows
from bench.report import RESULTS, machine_line
from models.data.dataset import MomDataset
from models.data.detections_replay import DetectionsReplay
from models.mom.evaluate import evaluate as per_frame_eval
from models.mom.runtime import MomRuntime
from service.learning.improve import ImproveOptions, Improver
from service.settings import LearningSettings
from service.stages import LocalizationModel

CAMERA = 1  # the bumped camera (0-based; the data set's Cam2)
CHAIN_KEYS = ("moda", "precision", "recall", "matched_mean_m", "mota", "idf1", "acc_0_3")


def per_frame(model: LocalizationModel, data: MomDataset) -> float:
    """Mean error (m) of every labelled row localized from its real boxes."""
    return float(per_frame_eval(model, data).metrics["mean"])  # type: ignore[arg-type]


def one_camera(data: MomDataset, camera: int) -> MomDataset:
    """The rows ``camera`` sees, with every other camera's box removed (its single views)."""
    rows = data.subset(data.visible()[:, camera])
    boxes = np.full_like(rows.boxes, np.nan)
    boxes[:, camera] = rows.boxes[:, camera]
    return MomDataset(rows.world, boxes, rows.frame, rows.track, rows.image_size)


def chain(result: dict[str, Any]) -> dict[str, float]:
    return {k: float(result[k]) for k in CHAIN_KEYS}


def improvement(
    variant: str, models: dict[str, Path], cmc1: MomDataset, cmc2: MomDataset, data: Path,
    work: Path, min_separation_m: float | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Serve CMC1 + CMC2 with the ``variant`` model, collect, one improvement run, score."""
    room = work / f"improve-{variant}"
    room.mkdir()
    marks = variant_rows(cmc1, variant).save(room / "marks.npz")
    replay = room / "cmc1_cmc2.npz"
    joined, offsets = chained(
        [DetectionsReplay.load(replay_path(data, s)) for s in ("CMC1", "CMC2")]
    )
    joined.save(replay)
    run = serve_learning(models[variant], replay, room, min_separation_m=min_separation_m)
    kept = room / "candidate_kept"

    def keep(path: Path) -> LocalizationModel:
        shutil.copytree(path, kept)  # the improver deletes a candidate it does not serve
        return MomRuntime.load(kept)

    options = ImproveOptions(time_budget_s=LearningSettings().improve_time_budget_s, nice_by=10)
    improver = Improver(room, run.labeler, run.pipeline, marks=marks, options=options, load=keep)
    started = time.monotonic()
    verdict = improver.run()
    train_s = time.monotonic() - started
    run.pipeline.stop()
    if verdict is None:
        raise RuntimeError(f"improvement failed: {improver.status()}")
    store = run.labeler.store
    labels = store.load() if store is not None else None
    cmc2_from = offsets[1] / cmc_data.FPS
    n_cmc2 = 0 if labels is None else int((labels.t >= cmc2_from).sum())
    n_all = 0 if labels is None else labels.n
    start = MomRuntime.load(models[variant])
    candidate = MomRuntime.load(kept)
    print(f"{variant}: {verdict.reason}", file=sys.stderr, flush=True)
    return {
        "variant": variant,
        "mark_rows": MomDataset.load(marks).n,
        "labels": {"CMC1": n_all - n_cmc2, "CMC2": n_cmc2},
        "rejected": run.labeler.stats()["rejected"],
        "verdict": verdict.as_dict(),
        "train_s": train_s,
        "start": {
            "per_frame_m": per_frame(start, cmc2),
            "policy": start.policy,
            **chain(evaluate(models[variant], "CMC2", data)),
        },
        "candidate": {
            "per_frame_m": per_frame(candidate, cmc2),
            "policy": candidate.policy,
            **chain(evaluate(kept, "CMC2", data)),
        },
    }


def healing(
    model_dir: Path, cmc2: MomDataset, data: Path, work: Path, max_positions: int | None = None
) -> dict[str, Any]:
    """The bump of :data:`CAMERA` at the start of CMC2 and its repair (module docstring)."""
    room = work / "heal"
    room.mkdir()
    plain = {s: DetectionsReplay.load(replay_path(data, s)) for s in ("CMC1", "CMC2")}
    size = tuple(int(v) for v in plain["CMC2"].image_size[CAMERA])
    h = bump_homography((size[0], size[1]))
    moved = {s: bumped_replay(r, CAMERA, -1, h) for s, r in plain.items()}
    joined, offsets = chained([plain["CMC1"], moved["CMC2"], moved["CMC1"]])
    joined.save(room / "replay.npz")
    bump_frame = offsets[1] + int(plain["CMC2"].frame.min())
    run = serve_learning(
        model_dir, room / "replay.npz", room, bumped=CAMERA, alert_frame=bump_frame
    )
    run.pipeline.stop()
    assert run.healer is not None
    status = run.healer.status()
    repaired = run.repaired_frame is not None
    start = MomRuntime.load(model_dir)
    fixed = MomRuntime.load(room / "model") if repaired else None
    bumped2 = bumped_dataset(cmc2, CAMERA, h)

    def seconds(frame: int | None) -> float | None:
        return None if frame is None else (frame - bump_frame) / cmc_data.FPS

    def errors(model: LocalizationModel | None, rows: MomDataset) -> dict[str, float | None]:
        if model is None:
            return {"all_m": None, "camera_m": None}
        alone = one_camera(rows, CAMERA)
        return {"all_m": per_frame(model, rows), "camera_m": per_frame(model, alone)}

    ground = Ground.build(data, "CMC2", replay_path(data, "CMC2"))
    moved_path = moved["CMC2"].save(room / "cmc2_bumped.npz")
    return {
        "camera": CAMERA,
        "check_after_s": seconds(run.check_frame),
        "repaired_after_s": seconds(run.repaired_frame),
        "status": status,
        "before": {**errors(start, cmc2), **chain(evaluate(model_dir, "CMC2", data))},
        "bumped": {**errors(start, bumped2), **chain(score(ground, serve(model_dir, moved_path)))},
        "repaired": {
            **errors(fixed, bumped2),
            **(chain(score(ground, serve(room / "model", moved_path))) if repaired else {}),
        },
    }


def run(args: argparse.Namespace) -> Path:
    data = Path(args.data)
    cmc1 = labelled_dataset(data, "CMC1")
    cmc2 = labelled_dataset(data, "CMC2")
    variants = [f"marks{n}" for n in args.marks]
    models = {v: trained_model(cmc1, v) for v in ("dense", *variants, "marks9")}
    dense = MomRuntime.load(models["dense"])
    results: dict[str, Any] = {
        "dense": {
            "per_frame_m": per_frame(dense, cmc2),
            "policy": dense.policy,
            "rows": cmc1.n,
            **chain(evaluate(models["dense"], "CMC2", data)),
        },
        "improvement": [],
        "min_separation_m": args.min_separation or LearningSettings().min_separation_m,
    }
    out = args.out or RESULTS / "self_learning_cmc.md"
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="cmc-learning-") as tmp:
        work = Path(tmp)
        for variant in variants:
            print(f"bench-real-learning: {variant} ...", file=sys.stderr, flush=True)
            results["improvement"].append(
                improvement(variant, models, cmc1, cmc2, data, work, args.min_separation)
            )
            write(results, out, time.perf_counter() - started)
        if not args.no_heal:
            print("bench-real-learning: bump ...", file=sys.stderr, flush=True)
            results["healing"] = healing(models["marks9"], cmc2, data, work)
    return write(results, out, time.perf_counter() - started)


def write(results: dict[str, Any], out: Path, seconds: float) -> Path:
    from bench.real.cmc_learning_report import report

    out.write_text(report(results, seconds, machine_line()))
    out.with_suffix(".json").write_text(json.dumps(results, indent=1, default=str) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder holding cmc/")
    parser.add_argument("--marks", type=int, nargs="+", default=[4, 9], choices=[4, 9])
    parser.add_argument("--no-heal", action="store_true", help="self-improvement only")
    parser.add_argument(
        "--min-separation",
        type=float,
        default=None,
        help="learning.min_separation_m for the self-labels (default: the daemon's)",
    )
    parser.add_argument("--out", type=Path, default=None, help="Markdown report")
    args = parser.parse_args(argv)
    if not cmc_data.available(args.data):
        print(f"bench-real-learning: no CMC data under {args.data}: skipped")
        return 0
    print(f"bench-real-learning: wrote {run(args)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
