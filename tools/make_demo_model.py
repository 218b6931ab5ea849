"""Build the shipped demo model (models/demo_model/) from the real detector's boxes on drawn frames.

``momloc demo`` sends the simulator's drawn frames through the shipped detector (NanoDet by
default), so the demo model is trained on exactly that: the training scene (the demo preset with a
*different* seed than the demo plays, so the map shows the model generalising to unseen walks) is
rendered, every frame set goes through the detector the demo uses (same kind, score threshold and
input size), and each detection is labelled with the simulator's true floor position of the
person whose true box it overlaps most (one-to-one, IoU >= 0.5, ``models.simulate.detector_view``).
Detections matching nobody are dropped (the demo's association rejects most ghosts by reprojection
error); a person the detector misses in a camera is a missing view there, as in real recordings.
So the model learns the real detector's box geometry (its bottom edge sits +1.7 % of the height
below the true foot for people < 100 px, -0.5 % for people > 200 px: bench/results/render_recall.md)
instead of the simulator's noise model.

``--boxes simulated`` trains on the simulator's noisy boxes instead (the previous demo model).

Deterministic: the scene seed, the detector and the trainer's seed fix the result. Cost: about
45 CPU-ms of drawing and detection per frame set (2000 sets: ~1.5 min on 2 idle cores; 10 min on
a 2-core host loaded at 10, 2026-12-01) and 1.5 min of training (9513 rows, 88 s).
Only ``encoder.onnx`` and ``model.json`` are kept (the service loads nothing else; the PyTorch
checkpoint is dropped to keep the repository small).

    .venv/bin/python tools/make_demo_model.py [--frames 4000] [--every 2] [--boxes rendered]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from models.mom.training.train import train_model  # noqa: E402
from models.simulate import Scene, get_config, simulate  # noqa: E402
from models.simulate.detector_view import detector_dataset  # noqa: E402
from service.demo import DEMO_FPS, DEMO_PEOPLE, DEMO_PRESET, DEMO_SEED, demo_settings  # noqa: E402
from service.settings import DEMO_MODEL_DIR  # noqa: E402

TRAIN_SEED = DEMO_SEED + 1000


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=4000, help="scene frames to draw from")
    parser.add_argument("--every", type=int, default=2, help="use every n-th frame (rendered)")
    parser.add_argument("--people", type=int, default=DEMO_PEOPLE + 2, help="people in training")
    parser.add_argument("--boxes", choices=("rendered", "simulated"), default="rendered",
                        help="rendered: the real detector on drawn frames (default); "
                        "simulated: the simulator's noisy boxes")  # fmt: skip
    parser.add_argument("--epochs", type=int, default=None, help="epoch cap (default: adaptive)")
    parser.add_argument("--out", type=Path, default=DEMO_MODEL_DIR, help="model directory")
    args = parser.parse_args(argv)
    progress = sys.stderr.isatty()
    started = time.monotonic()
    demo = {"preset": DEMO_PRESET, "train_seed": TRAIN_SEED, "frames": args.frames,
            "people": args.people, "fps": DEMO_FPS, "boxes": args.boxes,
            "made_by": "tools/make_demo_model.py"}  # fmt: skip
    if args.boxes == "simulated":
        result = simulate(
            DEMO_PRESET, frames=args.frames, seed=TRAIN_SEED, people=args.people, fps=DEMO_FPS
        )
        data = result.dataset
    else:
        from models.detector import create_detector

        settings = demo_settings(detections="rendered").detector
        options = {"input_size": settings.input_size} if settings.input_size else {}
        detector = create_detector(settings.kind, score_threshold=settings.score_threshold,
                                   threads=settings.threads, **options)  # fmt: skip
        config = get_config(DEMO_PRESET, people=args.people, fps=DEMO_FPS)
        scene = Scene(config, seed=TRAIN_SEED)
        data = detector_dataset(scene, range(0, args.frames, args.every), detector, progress)
        demo |= {"every": args.every, "detector": detector.describe(),
                 "score_threshold": settings.score_threshold,
                 "views_found": [round(float(v), 3) for v in data.visibility()]}  # fmt: skip
    demo["data_seconds"] = round(time.monotonic() - started, 1)
    print(f"training on {data.n} rows ({args.boxes} boxes) from {args.frames} frames of "
          f"{DEMO_PRESET}, {demo['data_seconds']} s to collect", flush=True)  # fmt: skip
    # model.json is written once, complete with the provenance, mode 0644 (common.atomic): the
    # container's non-root user reads it
    metrics = train_model(
        data, args.out, epochs=args.epochs, seed=0, progress=progress, extra_meta={"demo": demo}
    )
    for extra in ("model.pt",):
        (args.out / extra).unlink(missing_ok=True)
    shown = {k: v for k, v in metrics.items() if k != "val_history"}
    print(json.dumps(shown, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
