"""Floor prior study: how well per-camera floor homographies from a few marks localise the room.

``python -m bench.setup.floor_prior_study [--quick] [--no-mom]`` writes
``bench/results/floor_prior_study.md`` (``floor_prior_study_quick.md`` with ``--quick``).

Protocol (as ``bench/setup/setup_study.py``): a simulated person follows the ``momloc collect`` plan
on R×C marks of the room (collect seed 11), swaying and turning on each for the given seconds; the
prior (:class:`models.geometry.floor_prior.FloorPrior`) is fitted on those rows only and scored on a
dense recording of people walking everywhere in the same room (``simulate`` seed 12, 2000 frames).
The ceiling is the same prior fitted on dense ground truth (seed 13); for context, the calibrated
baseline with the simulator's *true* camera matrices (``models.geometry.calibrated_baseline``) and,
where it is cheap, the current MoM model (``train_model`` defaults) trained on the same marks.

The last table prototypes "prior + learned residual": a small MLP (torch, here only) takes
MoM-style box features and the prior's estimate and predicts a correction, trained on the mark
rows with a zero-initialised output layer, weight decay and an L2 penalty on the correction so
it stays at the prior where it has seen nothing.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table
from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.data.metrics import localization_metrics
from models.geometry.calibrated_baseline import localize, truncated
from models.geometry.floor_prior import FloorPrior
from models.simulate import get_config, simulate
from service.setup.collector import DatasetAppender, collect, plan_steps
from service.setup.feeds import SyntheticFeed
from service.setup.marks import grid_marks

COLLECT_SEED, TEST_SEED, DENSE_SEED = 11, 12, 13
POINT_SETS = ("foot", "centre", "both", "all")


def collect_marks(preset: str, grid: str, seconds: float, out: Path) -> MomDataset:
    """The guided collection of ``bench/setup/setup_study.py`` on any preset."""
    room = get_config(preset).room
    marks = grid_marks(grid, f"{room[0]}x{room[1]}")
    feed = SyntheticFeed(preset, COLLECT_SEED)
    steps = plan_steps(marks, seconds, start=(room[0] / 2, room[1] / 2))
    feed.prepare(steps)
    collect(feed, steps, DatasetAppender(out, feed.image_sizes))
    return MomDataset.load(out)


def score(pred: np.ndarray, test: MomDataset, fallback: np.ndarray) -> dict:
    """Metrics; rows without an estimate count at ``fallback`` (the marks' centre), not skipped."""
    missing = ~np.isfinite(pred).all(axis=1)
    pred = np.where(missing[:, None], fallback, pred)
    out = localization_metrics(pred, test.world, test.frame, test.track)
    return {**out, "missing": int(missing.sum())}


def metric_cells(m: dict, reference: float | None = None) -> list[str]:
    cells = [f"{m['mean']:.3f}", f"{m['median']:.3f}", f"{m['acc@0.3']:.1f}", f"{m['acc@0.5']:.1f}"]
    if reference is not None:
        cells.append(f"{m['mean'] / reference:.2f}×")
    return cells


def prior_score(data: MomDataset, test: MomDataset, points: str) -> tuple[dict, FloorPrior]:
    prior = FloorPrior.fit(data, points=points)
    pred = prior.predict(test.boxes, test.keypoints)[0]
    return score(pred, test, data.world[:, :2].mean(axis=0)), prior


def view_breakdown(prior: FloorPrior, test: MomDataset) -> list[tuple]:
    """Error by how the person is seen: views, and views with a box cut by the image border."""
    err = np.linalg.norm(prior.predict(test.boxes)[0] - test.world[:, :2], axis=1)
    seen = np.isfinite(test.boxes).all(axis=-1)
    cut = (truncated(test.boxes, test.image_size, "lrb") & seen).sum(axis=1)
    rows = []
    for views in range(1, test.num_cameras + 1):
        for cuts in range(views + 1):
            sel = (seen.sum(axis=1) == views) & (cut == cuts)
            if sel.sum():
                e = err[sel]
                rows.append((views, cuts, int(sel.sum()), f"{100 * sel.mean():.1f}",
                             f"{e.mean():.3f}", f"{100 * np.mean(e < 0.3):.1f}"))  # fmt: skip
    return rows


def smooth_tracks(xy, std, test: MomDataset, fps: float, accel: float = 1.0) -> np.ndarray:
    """Causal constant-velocity Kalman per (true) track with measurement std = the prior's std:
    what the daemon's tracker could do with the prior's error model (ids taken as known)."""
    out = xy.copy()
    order = np.lexsort((test.frame, test.track))
    state, cov, last, track = None, None, None, None
    for i in order:
        if not np.isfinite(xy[i]).all():
            continue
        r = np.eye(2) * max(std[i], 0.02) ** 2
        if test.track[i] != track or test.frame[i] - last > fps:  # new track or a long gap
            state, cov = np.r_[xy[i], 0.0, 0.0], np.diag([*np.diag(r), 1.0, 1.0])
        else:
            dt = (test.frame[i] - last) / fps
            f = np.eye(4)
            f[0, 2] = f[1, 3] = dt
            g = np.array([[dt**2 / 2, 0], [0, dt**2 / 2], [dt, 0], [0, dt]])
            state, cov = f @ state, f @ cov @ f.T + accel**2 * g @ g.T
            gain = cov[:, :2] @ np.linalg.inv(cov[:2, :2] + r)
            state = state + gain @ (xy[i] - state[:2])
            cov = cov - gain @ cov[:2]
        out[i], track, last = state[:2], test.track[i], test.frame[i]
    return out


def smoothing_table(prior: FloorPrior, test: MomDataset, fps: float) -> str:
    xy, std = prior.predict(test.boxes)
    single = np.isfinite(test.boxes).all(axis=-1).sum(axis=1) == 1
    fallback = test.world[:, :2].mean(axis=0)
    rows = []
    smooth = smooth_tracks(xy, std, test, fps)
    for label, pred in (("prior alone", xy), ("prior + causal Kalman", smooth)):
        for subset, sel in (("all rows", np.ones_like(single)), ("single-view rows", single)):
            m = score(pred[sel], test.subset(np.flatnonzero(sel)), fallback)
            rows.append((label, subset, m["n"], *metric_cells(m)))
    return markdown_table(
        ("Positions", "rows", "n", "mean (m)", "median", "Acc@0.3 %", "Acc@0.5 %"), rows
    )


def calibrated(sim, test: MomDataset) -> dict:
    pred = localize(test.boxes, sim.projections, method="triangulate", image_size=test.image_size)
    return score(pred, test, test.world[:, :2].mean(axis=0))


def mom_score(data: MomDataset, test: MomDataset, work: Path) -> dict:
    """The current MoM model (train_model defaults) on the same rows, through its runtime."""
    from models.mom.evaluate import evaluate
    from models.mom.runtime import MomRuntime
    from models.mom.training.train import train_model

    out = work / f"mom-{time.monotonic_ns()}"
    started = time.monotonic()
    train_model(data, out, progress=False)
    return {**evaluate(MomRuntime.load(out), test).metrics, "train_s": time.monotonic() - started}


def grid_table(
    quick: bool, test: MomDataset, work: Path, reference: float, dense_mom: float | None
) -> tuple[str, dict]:
    cases = [("2x2", 10), ("3x3", 20)] if quick else [
        (g, s) for g in ("2x2", "2x3", "3x3", "4x4") for s in (10, 20)
    ]  # fmt: skip
    rows, data_by_case = [], {}
    for grid, seconds in cases:
        data = collect_marks("indoor-2cam", grid, seconds, work / f"2cam-{grid}-{seconds}.npz")
        data_by_case[(grid, seconds)] = data
        for points in POINT_SETS:
            started = time.monotonic()
            m, _ = prior_score(data, test, points)
            fit_s = time.monotonic() - started
            versus = f"{m['mean'] / dense_mom:.2f}×" if dense_mom else "-"
            rows.append((grid, seconds, data.n, points, *metric_cells(m, reference), versus,
                         m["missing"], f"{fit_s:.2f}"))  # fmt: skip
            print(f"indoor-2cam {grid} {seconds}s {points}: {m['mean']:.3f} m", flush=True)
    table = markdown_table(
        ("Marks", "s/mark", "rows", "points", "mean (m)", "median", "Acc@0.3 %", "Acc@0.5 %",
         "vs ceiling", "vs dense MoM", "no estimate", "fit+predict s"),
        rows,
    )  # fmt: skip
    return table, data_by_case


def preset_table(quick: bool, work: Path) -> str:
    rows = []
    for preset in ("indoor-2cam", "indoor-4cam", "living-room"):
        sim = simulate(preset, frames=600 if quick else 2000, seed=TEST_SEED)
        test = sim.dataset
        dense = simulate(preset, frames=600 if quick else 2000, seed=DENSE_SEED).dataset
        marks = collect_marks(preset, "3x3", 20, work / f"{preset}-3x3.npz")
        cal = calibrated(sim, test)
        rows.append((preset, "calibrated triangulation (true P)", "-", *metric_cells(cal)))
        for label, data in (("3x3 marks, 20 s", marks), ("dense ground truth", dense)):
            for points in ("foot", "both", "all"):
                m, _ = prior_score(data, test, points)
                rows.append((preset, f"prior ({points}) on {label}", data.n, *metric_cells(m)))
        print(f"{preset}: done", flush=True)
    return markdown_table(
        ("Preset", "Method", "train rows", "mean (m)", "median", "Acc@0.3 %", "Acc@0.5 %"), rows
    )


# ----- prior + learned residual (prototype, torch only here) -----------------------------------


def residual_features(prior, boxes: np.ndarray, sizes: np.ndarray, centre, scale, boxes_in=True):
    """MoM-style inputs: per camera the box in [-1, 1] image units and a seen flag, plus the
    prior's estimate (normalised by the marks' spread) and log std. NaN prior → marks' centre.
    ``prior`` is a FloorPrior or precomputed (xy, std)."""
    xy, std = prior if isinstance(prior, tuple) else prior.predict(boxes)
    seen = np.isfinite(boxes).all(axis=-1)
    wh = np.tile(sizes, 2)[None]  # [1, K, 4]
    feats = np.where(seen[..., None], 2 * boxes / wh - 1, 0.0).reshape(len(boxes), -1)
    has = np.isfinite(xy).all(axis=1)
    xy = np.where(has[:, None], xy, centre)
    log_std = np.log(np.clip(np.where(has, std, 10.0), 1e-3, 10.0))
    x = np.concatenate([feats, seen, (xy - centre) / scale, log_std[:, None]], axis=1)
    if not boxes_in:
        x = x[:, -3:]
    return x.astype(np.float32), xy


def crossfit_prior(data: MomDataset) -> tuple[np.ndarray, np.ndarray]:
    """Each mark's rows predicted by a prior fitted without that mark, so the residual's
    targets are the prior's real errors away from its fitting points (falls back to the
    in-sample prior where leaving a mark out leaves a camera unfittable)."""
    xy, std = FloorPrior.fit(data).predict(data.boxes)
    marks = np.unique(np.round(data.world[:, :2] / 0.05), axis=0, return_inverse=True)[1].ravel()
    for m in np.unique(marks):
        rows = marks == m
        try:
            fold = FloorPrior.fit(data.subset(np.flatnonzero(~rows)))
        except MomlocError:
            continue
        xy[rows], std[rows] = fold.predict(data.boxes[rows])
    return xy, std


def train_residual(
    prior, data: MomDataset, *, epochs=400, penalty=1.0, decay=1e-2, seed=0, boxes_in=True,
    crossfit=False,
):  # fmt: skip
    """Fit the correction MLP on ``data`` (the marks); returns predict(boxes) → [B, 2]."""
    import torch

    torch.manual_seed(seed)
    torch.set_num_threads(1)
    centre = data.world[:, :2].mean(axis=0)
    scale = max(float(data.world[:, :2].std(axis=0).mean()), 0.5)
    sizes = data.image_size.astype(np.float64)
    train_prior = crossfit_prior(data) if crossfit else prior
    x, base = residual_features(train_prior, data.boxes, sizes, centre, scale, boxes_in)
    target = torch.tensor(data.world[:, :2] - base, dtype=torch.float32)
    net = torch.nn.Sequential(
        torch.nn.Linear(x.shape[1], 64), torch.nn.ReLU(),
        torch.nn.Linear(64, 64), torch.nn.ReLU(), torch.nn.Linear(64, 2),
    )  # fmt: skip
    torch.nn.init.zeros_(net[-1].weight)
    torch.nn.init.zeros_(net[-1].bias)
    opt = torch.optim.AdamW(net.parameters(), lr=3e-3, weight_decay=decay)
    inputs = torch.tensor(x)
    for _ in range(epochs):
        delta = net(inputs)
        fit = torch.linalg.vector_norm(delta - target, dim=1).mean()
        loss = fit + penalty * (delta**2).sum(dim=1).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()

    def predict(boxes: np.ndarray) -> np.ndarray:
        feats, xy = residual_features(prior, boxes, sizes, centre, scale, boxes_in)
        with torch.no_grad():
            return xy + net(torch.tensor(feats)).numpy().astype(np.float64)

    return predict


RESIDUALS = (
    ("boxes + prior in, L2 0", {"penalty": 0.0}),
    ("boxes + prior in, L2 10", {"penalty": 10.0}),
    ("boxes + prior in, L2 10, cross-fitted", {"penalty": 10.0, "crossfit": True}),
    ("prior only in, L2 1, cross-fitted", {"penalty": 1.0, "boxes_in": False, "crossfit": True}),
)


def residual_table(cases: dict, test: MomDataset, work: Path, mom: bool) -> str:
    rows = []
    for (grid, seconds), data in cases.items():
        prior = FloorPrior.fit(data, points="both")
        fallback = data.world[:, :2].mean(axis=0)
        label = f"{grid}, {seconds} s"
        alone = score(prior.predict(test.boxes)[0], test, fallback)
        rows.append((label, "prior alone (both)", *metric_cells(alone), "-"))
        for name, options in RESIDUALS:
            started = time.monotonic()
            predict = train_residual(prior, data, **options)
            m = score(predict(test.boxes), test, fallback)
            rows.append((label, f"prior + residual: {name}", *metric_cells(m),
                         f"{time.monotonic() - started:.0f}"))  # fmt: skip
            print(f"{label} residual {name}: {m['mean']:.3f} m", flush=True)
        if mom and (grid, seconds) in (("2x2", 10), ("3x3", 20)):
            m = mom_score(data, test, work)
            cells = (*metric_cells(m), f"{m['train_s']:.0f}")
            rows.append((label, "current MoM (train_model)", *cells))
            print(f"{label} MoM: {m['mean']:.3f} m", flush=True)
    return markdown_table(
        ("Marks", "Model", "mean (m)", "median", "Acc@0.3 %", "Acc@0.5 %", "train s"), rows
    )


def run(quick: bool, mom: bool) -> Path:
    started = time.monotonic()
    test = simulate("indoor-2cam", frames=600 if quick else 2000, seed=TEST_SEED).dataset
    dense = simulate("indoor-2cam", frames=600 if quick else 2000, seed=DENSE_SEED).dataset
    ceiling = {p: prior_score(dense, test, p)[0] for p in POINT_SETS}
    reference = ceiling["both"]["mean"]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        dense_mom = mom_score(dense, test, work) if mom else None
        if dense_mom:
            print(f"dense MoM: {dense_mom['mean']:.3f} m", flush=True)
        grids, cases = grid_table(
            quick, test, work, reference, dense_mom["mean"] if dense_mom else None
        )
        ceiling_table = markdown_table(
            ("Fitted on", "rows", "points", "mean (m)", "median", "Acc@0.3 %", "Acc@0.5 %"),
            [("dense ground truth", dense.n, p, *metric_cells(m)) for p, m in ceiling.items()]
            + ([("dense ground truth", dense.n, "MoM (train_model)", *metric_cells(dense_mom))]
               if dense_mom else []),
        )  # fmt: skip
        nine = cases.get(("3x3", 20)) or next(iter(cases.values()))
        breakdown = markdown_table(
            ("views", "cut views", "rows", "% of rows", "mean (m)", "Acc@0.3 %"),
            view_breakdown(FloorPrior.fit(nine, points="both"), test),
        )
        smoothing = smoothing_table(
            FloorPrior.fit(nine, points="both"), test, get_config("indoor-2cam").fps
        )
        presets = preset_table(quick, work)
        chosen = {k: v for k, v in cases.items() if k in (("2x2", 10), ("3x3", 20))}
        residual = residual_table(chosen, test, work, mom)
    name = "floor_prior_study_quick.md" if quick else "floor_prior_study.md"
    path = RESULTS / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        "# Floor prior study (calibration-free homographies from floor marks)\n\n"
        f"{machine_line()} Whole study: {time.monotonic() - started:.0f} s.\n\n"
        f"Command: `python -m bench.setup.floor_prior_study{' --quick' if quick else ''}`. Test: "
        f"dense "
        f"walks, {test.n} person instances over the whole 10 × 10 m indoor-2cam room (simulate "
        f"seed {TEST_SEED}); marks collected with seed {COLLECT_SEED} (guided collection, "
        "swaying/turning on each mark); errors in metres, accuracies in %. 'points': which box "
        "point the homographies use (foot = bottom-centre, centre = box centre, both = the two "
        "fused with their joint error model, all = both + the ankles' middle from COCO keypoints, "
        "for a pose detector). 'vs ceiling' = mean error / the prior fitted on "
        f"dense ground truth (both points, {reference:.3f} m); 'vs dense MoM' = mean error / the "
        "current MoM model trained on the same dense ground truth (the issue's target: ≤ 1.20×). "
        "Rows the prior cannot place "
        "(no fitted camera sees them) count at the marks' centre ('no estimate').\n\n"
        "## Marks and seconds per mark (indoor-2cam)\n\n"
        f"{grids}\n\n## Ceiling: the prior fitted on dense ground truth\n\n{ceiling_table}\n\n"
        "## Where the error is (3x3 marks, 20 s, both points)\n\n"
        "Rows by number of cameras that see the person and how many of those boxes touch a "
        f"left, right or bottom image border.\n\n{breakdown}\n\n"
        "## With temporal smoothing (3x3 marks, 20 s, both points)\n\n"
        "A causal constant-velocity Kalman filter per track (true track ids; white acceleration "
        "1 m/s²) with the prior's std as measurement noise: what the daemon's tracker can add "
        "when it is given the prior's std. Single-view rows are where per-frame geometry runs "
        f"out.\n\n{smoothing}\n\n"
        "## Other scenes (3x3 marks, 20 s; living-room has lens distortion)\n\n"
        f"{presets}\n\n## Prior + learned residual (prototype) vs the current MoM model\n\n"
        f"{residual}\n"
    )
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two small cases, for a smoke run")
    parser.add_argument("--no-mom", action="store_true", help="skip training the MoM model")
    args = parser.parse_args()
    print(run(args.quick, not args.no_mom))


if __name__ == "__main__":
    main()
