"""The CMC bench's set-up side: labels from CMC1's real boxes, replays, trained models (cached).

Everything reaches the product the way a user's data would: the evaluation pairing
(``bench.real.cmc_data.pair_boxes``, the one use of the projection matrices) writes MOTChallenge
files *with ids* plus a positions file, and ``momloc import`` turns them into the dataset v1
that ``models.mom.training.train`` fits; the raw detector files go through ``momloc import`` as a
detections replay. Derived files live in a gitignored cache (``.cache/real_cmc`` at the repo root)
and never in the repository (the data set's terms: evaluation only).

Models are cached under a key hashing the training rows, the variant, the seed and the source
of the training code, so a re-run reuses them and any change retrains. Two variants:

``dense``   every labelled CMC1 row (3 people walking over the whole area)
``marks9``  the CMC1 rows within 0.3 m of a 3 x 3 grid of marks at the cell centres of the
            tracking area: what a user taping 9 marks and standing on them would record
``marks4``  the same with a 2 x 2 grid (the self-learning bench's start, ``cmc_self_learning``)
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np

from bench.real import cmc_data
from common.atomic import atomic_write_json, atomic_write_text, replace_folder
from common.errors import MomlocError
from models.data.dataset import MomDataset

ROOT = Path(__file__).resolve().parents[2]
CACHE = ROOT / ".cache" / "real_cmc"
SEED = 0
MARK_RADIUS_M = 0.3
VARIANTS = ("dense", "marks9")
TRAIN_SOURCES = (
    "models/mom/training/train.py",
    "models/mom/training/torch_model.py",
    "models/mom/sampling.py",
    "models/mom/prior_policy.py",
    "models/geometry/floor_prior.py",
    "models/mom/setup_area.py",
    "models/mom/training/export.py",
)


def mark_grid(side: int = 3) -> np.ndarray:
    """The ``side`` x ``side`` marks [side², 2]: cell centres of a grid over the tracking area."""
    (x0, x1), (y0, y1) = cmc_data.AREA
    xs = x0 + (np.arange(side) + 0.5) * (x1 - x0) / side
    ys = y0 + (np.arange(side) + 0.5) * (y1 - y0) / side
    return np.array([(x, y) for x in xs for y in ys])


def near_marks(xy: np.ndarray, marks: np.ndarray, radius: float = MARK_RADIUS_M) -> np.ndarray:
    """Bool [N]: the floor positions ``xy`` [N, 2] within ``radius`` of some mark."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    return np.linalg.norm(xy[:, None] - marks[None], axis=2).min(axis=1) <= radius


def _import(argv: list[str]) -> None:
    from service.cli import main

    if main(["import", *argv]) != 0:
        raise MomlocError(f"momloc import {' '.join(argv)}: failed")


def write_labels(data: Path, sequence: str, folder: Path) -> tuple[list[Path], Path]:
    """MOT files with the evaluation pairing's ids (one per camera) and the positions file."""
    from models.data.mot_import import read_mot

    folder.mkdir(parents=True, exist_ok=True)
    matrices = cmc_data.projections(data)
    truth = cmc_data.truth(data, sequence)
    mot_paths = []
    for k, source in enumerate(cmc_data.detection_files(data, sequence)):
        boxes = read_mot(source)
        lines = []
        for f in np.unique(truth.frame):
            rows = truth.at(f)
            sel = np.flatnonzero(boxes.frame == f)
            owner = cmc_data.pair_boxes(
                matrices[k], truth.world[rows], truth.z_c[rows], boxes.boxes[sel]
            )
            for i, r in zip(sel, owner, strict=True):
                if r >= 0:
                    x0, y0, x1, y1 = boxes.boxes[i].tolist()
                    lines.append(
                        f"{f},{truth.id[rows[r]]},{x0:.3f},{y0:.3f},{x1 - x0:.3f},{y1 - y0:.3f},-1"
                    )
        path = folder / f"cam{k + 1}.txt"
        atomic_write_text(path, "\n".join(lines) + "\n")
        mot_paths.append(path)
    positions = folder / "positions.txt"
    atomic_write_text(
        positions,
        "# frame, id, x, y (m)\n"
        + "".join(
            f"{f},{i},{x:.5f},{y:.5f}\n"
            for f, i, (x, y) in zip(truth.frame, truth.id, truth.world, strict=True)
        ),
    )
    return mot_paths, positions


def size_args() -> list[str]:
    return ["--image-size", "{}x{}".format(*cmc_data.IMAGE_SIZE), "--fps", f"{cmc_data.FPS:g}"]


def labelled_dataset(data: Path, sequence: str = "CMC1", cache: Path = CACHE) -> MomDataset:
    """``sequence``'s real boxes paired with the true positions, through ``momloc import``."""
    folder = cache / f"labels_{sequence}"
    out = folder / "dataset.npz"
    mot, positions = write_labels(data, sequence, folder)
    _import(
        [
            "--mot",
            *map(str, mot),
            *size_args(),
            "--positions",
            str(positions),
            "--dataset",
            str(out),
        ]
    )
    return MomDataset.load(out)


def replay_path(data: Path, sequence: str, cache: Path = CACHE) -> Path:
    """``sequence``'s raw detector boxes (all cameras, ids ignored) as a replay, via import."""
    out = cache / f"replay_{sequence}.npz"
    files = [str(p) for p in cmc_data.detection_files(data, sequence)]
    _import(["--mot", *files, *size_args(), "--replay", str(out)])
    return out


def variant_rows(dataset: MomDataset, variant: str) -> MomDataset:
    if variant == "dense":
        return dataset
    marks = {"marks9": 3, "marks4": 2}.get(variant)
    if marks is not None:
        return dataset.subset(near_marks(dataset.world[:, :2], mark_grid(marks)))
    raise MomlocError(f"variant {variant}: not one of {', '.join((*VARIANTS, 'marks4'))}")


def _key(dataset: MomDataset, variant: str) -> str:
    digest = hashlib.sha256()
    for name, array in sorted(dataset.arrays().items()):
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(array).tobytes())
    digest.update(f"{variant}:{SEED}".encode())
    for source in TRAIN_SOURCES:
        digest.update((ROOT / source).read_bytes())
    return digest.hexdigest()[:16]


def trained_model(dataset: MomDataset, variant: str, cache: Path = CACHE) -> Path:
    """The model of ``variant`` trained on ``dataset`` with ``models.mom.training.train``
    (cached)."""
    rows = variant_rows(dataset, variant)
    out = cache / f"model_{variant}_{_key(rows, variant)}"
    if (out / "model.json").is_file():
        return out
    from models.mom.training.train import train_model

    tmp = out.with_name(out.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    train_model(rows, tmp, seed=SEED, progress=False)
    atomic_write_json(tmp / "bench_rows.json", {"rows": rows.n, "variant": variant})
    return replace_folder(tmp, out)


def encoder_only(model_dir: Path) -> Path:
    """A copy of ``model_dir`` served by its encoder alone (``floor_prior`` policy ``"mom"``).

    Why: ``models.mom.prior_policy`` picks the serving policy on validation rows inside the labelled
    area, so a small change in the labels flips a dense model between "encoder" and "blend";
    the bench serves both to show what that choice does to boxes from outside the area.
    """
    out = model_dir.with_name(model_dir.name + "_encoder")
    if (out / "model.json").is_file():
        return out
    tmp = out.with_name(out.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(model_dir, tmp)
    meta = json.loads((model_dir / "model.json").read_text())
    meta["floor_prior"] = {**meta["floor_prior"], "policy": "mom", "weights": [0.0, 0.0, 0.0]}
    atomic_write_json(tmp / "model.json", meta)
    return replace_folder(tmp, out)
