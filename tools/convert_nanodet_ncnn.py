"""Convert the shipped NanoDet ONNX graph to ncnn (``nanodet_person.ncnn.param`` / ``.bin``).

Why: ncnn is NanoDet's native runtime and, measured on this project's machine, needs less CPU per
pair of frames than onnxruntime (``bench/results/detector_runtimes.md``). Nothing may be
converted at run time, so the ncnn files are made here once, committed with their SHA-256 and
checked by the test suite against the same TensorFlow reference outputs as the ONNX file.

It runs in a throwaway virtual environment (pnnx pulls torch)::

    python3 -m venv /tmp/ncnnvenv
    /tmp/ncnnvenv/bin/pip install pnnx==20261020 ncnn==1.0.20261020 onnx==1.23.2
    /tmp/ncnnvenv/bin/python tools/convert_nanodet_ncnn.py

Steps:

1. The source is the committed ``nanodet_person.onnx``, checked against its ``.sha256``.
2. Graph surgery before pnnx, because pnnx cannot map two parts of that graph to ncnn layers:

   - the **input prefix** (uint8 cast, BGR mean/std, NHWC → NCHW transpose) is cut off: ncnn
     normalises in ``Mat.substract_mean_normalize`` on its own NCHW float input, so the ncnn
     graph's input ``in0`` is the normalised image, one frame per call (ncnn has no batch);
   - the **explicit Pad nodes** (tf2onnx writes TensorFlow's SAME padding as a Pad before each
     convolution and the max-pool) are folded into the ``pads`` of the Conv/MaxPool after them
     (zero for a convolution; -inf for the max-pool, which is ONNX MaxPool's own padding).

   The head (person score, the GFL distance softmax and its expectation) stays in the graph, so
   the output ``out0`` [A, 5] is the ONNX output ``person`` for one frame.
3. ``pnnx`` converts the graph with two input shapes (320×256 and 416×320), so reshapes stay
   size-independent; its ncnn writer stores weights as float16 (half the file size).
4. Parity: ncnn runs the reference batch of ``nanodet_reference.npz`` (TensorFlow's outputs on
   the original TF.js graph) frame by frame and must reproduce its person scores and distances.

The pnnx version is pinned: its output is byte-identical from run to run for one version, and the
committed ``.sha256`` files pin what we ship.
"""

from __future__ import annotations

import argparse
import hashlib
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

WEIGHTS = Path(__file__).resolve().parents[1] / "models" / "detector" / "weights"
SOURCE = WEIGHTS / "nanodet_person.onnx"
REFERENCE = WEIGHTS / "nanodet_reference.npz"
STEM = "nanodet_person.ncnn"
PNNX_VERSION = "20261020"
SHAPES = ("[1,3,256,320]", "[1,3,320,416]")
MEAN_BGR = (103.53, 116.28, 123.675)
STD_BGR = (57.375, 57.12, 58.395)
PREFIX = ("Cast", "Sub", "Mul", "Transpose")
SCORE_ATOL, DISTANCE_ATOL = 5e-4, 3e-3


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def fold_pads(graph, nodes: list) -> set[int]:
    """Fold every Pad node of ``nodes`` into the Conv/MaxPool after it (step 2); the ids of the
    folded Pad nodes, for the caller to drop. Shared with ``tools/quantize_nanodet.py``."""
    from onnx import helper, numpy_helper

    initializers = {init.name: init for init in graph.initializer}
    consumers: dict[str, list] = {}
    for node in nodes:
        for name in node.input:
            consumers.setdefault(name, []).append(node)
    dropped = set()
    for node in nodes:
        if node.op_type != "Pad":
            continue
        pads = numpy_helper.to_array(initializers[node.input[1]])
        value = (
            float(numpy_helper.to_array(initializers[node.input[2]]))
            if len(node.input) > 2 and node.input[2]
            else 0.0
        )
        (after,) = consumers[node.output[0]]
        folds = (after.op_type == "Conv" and value == 0.0) or (
            after.op_type == "MaxPool" and value == float("-inf")
        )
        if not folds or pads[[0, 1, 4, 5]].any():  # NCHW: only H and W may be padded
            raise SystemExit(f"{node.name}: a Pad that cannot be folded into {after.op_type}")
        spatial = [int(pads[2]), int(pads[3]), int(pads[6]), int(pads[7])]
        after.attribute.append(helper.make_attribute("pads", spatial))
        after.input[0] = node.input[0]
        dropped.add(id(node))
    return dropped


def load_graph(source: Path, prefix: tuple[str, ...]) -> tuple[Any, list]:
    """The ONNX model and its nodes, checked to start with the ``prefix`` op types."""
    import onnx

    model = onnx.load(source)
    nodes = list(model.graph.node)
    if tuple(node.op_type for node in nodes[: len(prefix)]) != prefix:
        raise SystemExit(f"{source}: the graph does not start with {prefix}")
    return model, nodes


def ncnn_ready_onnx(source: Path, output: Path) -> None:
    """The shipped graph without its input prefix and with every Pad folded (step 2)."""
    import onnx
    from onnx import helper

    model, nodes = load_graph(source, PREFIX)
    graph = model.graph
    dropped = fold_pads(graph, nodes) | {id(node) for node in nodes[: len(PREFIX)]}
    kept = [node for node in nodes if id(node) not in dropped]
    new_input = nodes[len(PREFIX) - 1].output[0]
    del graph.node[:]
    graph.node.extend(kept)
    del graph.input[:]
    graph.input.append(
        helper.make_tensor_value_info(new_input, onnx.TensorProto.FLOAT, [1, 3, "H", "W"])
    )
    onnx.checker.check_model(model)
    onnx.save(model, output)


def run_pnnx(onnx_path: Path) -> tuple[Path, Path]:
    pnnx = shutil.which("pnnx") or str(Path(sys.executable).with_name("pnnx"))
    subprocess.run(
        [pnnx, onnx_path.name, f"inputshape={SHAPES[0]}", f"inputshape2={SHAPES[1]}"],
        cwd=onnx_path.parent,
        check=True,
        capture_output=True,
    )
    stem = onnx_path.with_suffix("")
    return stem.with_suffix(".ncnn.param"), stem.with_suffix(".ncnn.bin")


def run_ncnn(param: Path, weights: Path, batch: np.ndarray) -> np.ndarray:
    """[N, A, 5] from ncnn, one frame per extractor, normalised by ncnn itself."""
    import ncnn

    net = ncnn.Net()
    net.opt.num_threads = 1
    net.load_param(str(param))
    net.load_model(str(weights))
    outputs = []
    for image in batch:
        height, width = image.shape[:2]
        mat = ncnn.Mat.from_pixels(image, ncnn.Mat.PixelType.PIXEL_BGR, width, height)
        mat.substract_mean_normalize(MEAN_BGR, [1.0 / s for s in STD_BGR])
        with net.create_extractor() as extractor:
            extractor.input("in0", mat)
            _, out = extractor.extract("out0")
            outputs.append(np.array(out))
    return np.stack(outputs)


def check_parity(param: Path, weights: Path) -> float:
    """Largest score difference to TensorFlow's reference; raises when outside tolerance."""
    reference = np.load(REFERENCE)
    noise = np.random.default_rng(int(reference["noise_seed"])).integers(
        0, 256, reference["astronaut"].shape, dtype=np.uint8
    )
    ours = run_ncnn(param, weights, np.stack([reference["astronaut"], noise]))
    expected = reference["person"]
    if ours.shape != expected.shape:
        raise SystemExit(f"ncnn output {ours.shape}, reference {expected.shape}")
    score_error = float(np.abs(ours[..., 0] - expected[..., 0]).max())
    confident = expected[..., 0] > 0.05
    distance_error = float(np.abs(ours[..., 1:][confident] - expected[..., 1:][confident]).max())
    if score_error > SCORE_ATOL or distance_error > DISTANCE_ATOL:
        raise SystemExit(f"parity lost: score {score_error:.2g}, distance {distance_error:.2g}")
    return score_error


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out-dir", type=Path, default=WEIGHTS)
    args = parser.parse_args(argv)
    expected = (WEIGHTS / f"{SOURCE.name}.sha256").read_text().split()[0]
    if sha256(SOURCE) != expected:
        raise SystemExit(f"{SOURCE}: sha256 differs from its .sha256 file")
    with tempfile.TemporaryDirectory() as tmp:
        ready = Path(tmp) / "nanodet_person.onnx"
        ncnn_ready_onnx(SOURCE, ready)
        param, weights = run_pnnx(ready)
        score_error = check_parity(param, weights)
        args.out_dir.mkdir(parents=True, exist_ok=True)
        for made, suffix in ((param, ".param"), (weights, ".bin")):
            target = args.out_dir / f"{STEM}{suffix}"
            shutil.copyfile(made, target)
            (args.out_dir / f"{target.name}.sha256").write_text(
                f"{sha256(target)}  {target.name}\n"
            )
            print(f"wrote {target} ({target.stat().st_size / 1e6:.1f} MB), sha256 {sha256(target)}")
    print(f"parity with TensorFlow's reference: largest score difference {score_error:.2g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
