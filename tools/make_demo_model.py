"""Build the shipped demo model (models/demo_model/) with our own simulator and trainer.

The demo scene (service.demo) is simulated with a *different* seed than the one the demo plays,
so the map shows the model generalising to unseen walks, not replaying its training data. The
same 30 fps as the demo keeps walking speed per frame identical. Only ``encoder.onnx`` and
``model.json`` are kept (the service loads nothing else; the PyTorch checkpoint is dropped to keep
the repository small).

    .venv/bin/python tools/make_demo_model.py [--frames 4000] [--epochs N] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from models.simulate import simulate  # noqa: E402
from models.train import train_model  # noqa: E402
from service.demo import DEMO_FPS, DEMO_PEOPLE, DEMO_PRESET, DEMO_SEED  # noqa: E402
from service.settings import DEMO_MODEL_DIR  # noqa: E402

TRAIN_SEED = DEMO_SEED + 1000


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=4000, help="simulated frames to train on")
    parser.add_argument("--people", type=int, default=DEMO_PEOPLE + 2, help="people in training")
    parser.add_argument("--epochs", type=int, default=None, help="epoch cap (default: adaptive)")
    parser.add_argument("--out", type=Path, default=DEMO_MODEL_DIR, help="model directory")
    args = parser.parse_args(argv)
    result = simulate(
        DEMO_PRESET, frames=args.frames, seed=TRAIN_SEED, people=args.people, fps=DEMO_FPS
    )
    data = result.dataset
    print(f"training on {data.n} rows from {args.frames} frames of {DEMO_PRESET}", flush=True)
    progress = sys.stderr.isatty()
    metrics = train_model(data, args.out, epochs=args.epochs, seed=0, progress=progress)
    for extra in ("model.pt",):
        (args.out / extra).unlink(missing_ok=True)
    meta = json.loads((args.out / "model.json").read_text())
    meta["demo"] = {
        "preset": DEMO_PRESET,
        "train_seed": TRAIN_SEED,
        "frames": args.frames,
        "people": args.people,
        "fps": DEMO_FPS,
        "made_by": "tools/make_demo_model.py",
    }
    (args.out / "model.json").write_text(json.dumps(meta, indent=1) + "\n")
    (args.out / "model.json").chmod(0o644)  # readable by the container's non-root user
    shown = {k: v for k, v in metrics.items() if k != "val_history"}
    print(json.dumps(shown, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
