"""Quantize the shipped NanoDet graph to INT8 for OpenVINO (and, measured only, onnxruntime).

Why: at FP32 every runtime needed about twice the CPU budget of a pair of 640×480 frames on a
2-core machine (``bench/results/detector_runtimes.md``); 8-bit weights and activations roughly
halve the convolutions' cost on AVX2 CPUs while keeping recall on the hand-checked vtest boxes
(same file). Nothing may be converted at run time, so the INT8 files are made here once,
committed with their SHA-256 and checked by the test suite.

It runs in a throwaway virtual environment (NNCF pulls many packages the daemon does not need)::

    python3 -m venv /tmp/quantvenv
    /tmp/quantvenv/bin/pip install nncf==3.4.0 openvino==2026.4.1 onnx==1.23.2 \\
        onnxruntime==1.32.0 opencv-python-headless==5.1.0.95
    /tmp/quantvenv/bin/python tools/quantize_nanodet.py

Steps:

1. The source is the committed ``nanodet_person.onnx``, checked against its ``.sha256``.
2. A **lean FP32 graph**, the same function: tf2onnx's explicit Pad nodes are folded into the
   Conv/MaxPool after them (as for ncnn, ``tools/convert_nanodet_ncnn.py``), the division by the
   BGR standard deviation is folded into the first convolution's weights (exact: zero padding
   commutes with a per-channel scale), and the mean is subtracted after the NHWC → NCHW
   transpose, where it broadcasts per channel plane. The input stays uint8 BGR NHWC ``images``
   and the output ``person``, so the runtimes' code does not change.
3. **Calibration frames**: 50 frames of ``vtest.avi`` (Debian ``opencv-doc``) that are *not* among
   the hand-checked frames the accuracy bench scores (those are multiples of 15; these are
   15·k + 7), resized like the daemon does (640×480, then 320×256, INTER_AREA). Calibration only
   sets the activation ranges; recall is then measured on the held-out labelled frames.
4. **OpenVINO** (shipped): NNCF post-training quantization (``MIXED`` preset: symmetric
   weights, asymmetric activations) of the lean graph → ``nanodet_person.int8.xml`` / ``.bin``
   (IR with dynamic batch and size, reshaped per input shape at run time like the ONNX file).
5. **onnxruntime** (a candidate, only with ``--onnxruntime-candidate PATH``): static
   post-training quantization, QDQ format, weights int8 per channel, activations uint8 per
   tensor (MinMax over the calibration frames). Not shipped: it lost more than a point of recall
   on the vtest boxes and needed more CPU than OpenVINO's (``bench.detector.runtimes
   --candidate``, ``bench/results/detector_runtimes.md``).
   In both, the three output convolutions and the decoding after them (sigmoid, distance
   softmax, expectation) stay float (:func:`float_head`).
6. Parity: the INT8 model runs TensorFlow's reference batch of ``nanodet_reference.npz`` and
   must find the astronaut at the original graph's best anchor (:func:`check_parity`); 8-bit
   activations cannot reproduce float scores to 1e-4, so the check is on the decisive outputs,
   and recall is the bench's job.

The tool versions are pinned: the files are deterministic for one set of versions, and the
committed ``.sha256`` files pin what we ship.
"""

from __future__ import annotations

import argparse
import hashlib
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from convert_nanodet_ncnn import fold_pads, load_graph

WEIGHTS = Path(__file__).resolve().parents[1] / "models" / "detector" / "weights"
SOURCE = WEIGHTS / "nanodet_person.onnx"
REFERENCE = WEIGHTS / "nanodet_reference.npz"
VIDEO = Path("/usr/share/doc/opencv-doc/examples/data/vtest.avi")
VIDEO_SHA256 = "45cddc9490be69345cbdab64ca583be65987e864ca408038e648db99e10516cf"
CALIBRATION_FRAMES = tuple(15 * k + 7 for k in range(50))
FRAME_SIZE, INPUT_SIZE = (640, 480), (320, 256)
PREFIX = ("Cast", "Sub", "Mul", "Transpose", "Pad", "Conv")
INPUT_NAME, OUTPUT_NAME = "images", "person"
STEM = "nanodet_person.int8"
# The astronaut (the reference batch's first frame): INT8 must keep its best anchor's score
# within this of TensorFlow's and its decoded box (best anchor) within these stride units.
SCORE_ATOL, DISTANCE_ATOL = 0.08, 1.5


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def lean_graph(source: Path, output: Path) -> None:
    """The shipped graph with Pads folded and the normalisation moved (step 2)."""
    import onnx
    from onnx import helper, numpy_helper

    model, nodes = load_graph(source, PREFIX)
    graph = model.graph
    cast, subtract, multiply, _, _, first_conv = nodes[: len(PREFIX)]
    initializers = {init.name: init for init in graph.initializer}
    mean = numpy_helper.to_array(initializers[subtract.input[1]]).astype(np.float32)
    inverse_std = numpy_helper.to_array(initializers[multiply.input[1]]).astype(np.float32)
    weights = numpy_helper.to_array(initializers[first_conv.input[1]])
    scaled = (weights * inverse_std[None, :, None, None]).astype(np.float32)
    for name in (first_conv.input[1], subtract.input[1], multiply.input[1]):
        graph.initializer.remove(initializers[name])
    graph.initializer.extend(
        [
            numpy_helper.from_array(scaled, first_conv.input[1]),
            numpy_helper.from_array(mean.reshape(1, 3, 1, 1), "bgr_mean_nchw"),
        ]
    )
    dropped = fold_pads(graph, nodes) | {id(node) for node in nodes[1:4]}
    prefix = [
        helper.make_node("Transpose", [cast.output[0]], ["images_nchw"], perm=[0, 3, 1, 2]),
        helper.make_node("Sub", ["images_nchw", "bgr_mean_nchw"], [first_conv.input[0]]),
    ]
    kept = [node for node in nodes if id(node) not in dropped]
    for index, node in enumerate(kept):
        node.name = node.name or f"decode_{node.op_type}_{index}"  # quantizers exclude by name
    del graph.node[:]
    graph.node.extend([kept[0], *prefix, *kept[1:]])
    onnx.checker.check_model(model)
    onnx.save(model, output)


def float_head(lean: Path) -> list[str]:
    """The nodes that stay float: the three output convolutions (score logit and distance bins
    of one stride each, split after them) and everything after them. Quantized, the score logit
    shares an 8-bit range with the 32 bin logits and the concatenated output ``person`` one with
    the distances (steps of 0.03 in the score): the reference astronaut's best score fell from
    0.73 to 0.19."""
    import onnx

    nodes = list(onnx.load(lean).graph.node)
    consumers: dict[str, list] = {}
    for node in nodes:
        for name in node.input:
            consumers.setdefault(name, []).append(node)
    heads = [
        n
        for n in nodes
        if n.op_type == "Conv" and [c.op_type for c in consumers[n.output[0]]] == ["Split"]
    ]
    if len(heads) != 3:
        raise SystemExit(f"{lean}: expected 3 head convolutions before a Split, found {len(heads)}")
    after, pending = {id(n): n for n in heads}, list(heads)
    while pending:
        for name in pending.pop().output:
            for consumer in consumers.get(name, []):
                if id(consumer) not in after:
                    after[id(consumer)] = consumer
                    pending.append(consumer)
    return [node.name for node in after.values()]


def calibration_frames() -> np.ndarray:
    """uint8 BGR [50, 256, 320, 3]: the unlabelled vtest frames of step 3."""
    import cv2

    if not VIDEO.is_file() or sha256(VIDEO) != VIDEO_SHA256:
        raise SystemExit(f"{VIDEO}: missing or changed (apt-get install opencv-doc)")
    capture = cv2.VideoCapture(str(VIDEO))
    frames, index, wanted = [], 0, set(CALIBRATION_FRAMES)
    while len(frames) < len(wanted):
        ok, frame = capture.read()
        if not ok:
            raise SystemExit(f"{VIDEO}: ended at frame {index}")
        if index in wanted:
            frame = cv2.resize(frame, FRAME_SIZE, interpolation=cv2.INTER_AREA)
            frames.append(cv2.resize(frame, INPUT_SIZE, interpolation=cv2.INTER_AREA))
        index += 1
    capture.release()
    return np.stack(frames)


def quantize_onnxruntime(lean: Path, frames: np.ndarray, output: Path) -> None:
    """Step 4: QDQ static quantization of the convolutions and the layers between them."""
    from onnxruntime.quantization import (
        CalibrationDataReader,
        QuantFormat,
        QuantType,
        quantize_static,
        shape_inference,
    )

    class Frames(CalibrationDataReader):
        def __init__(self) -> None:
            self.pending = iter(frames[i : i + 1] for i in range(len(frames)))

        def get_next(self) -> dict[str, np.ndarray] | None:
            batch = next(self.pending, None)
            return None if batch is None else {INPUT_NAME: batch}

    prepared = lean.with_name("lean_prepared.onnx")
    shape_inference.quant_pre_process(str(lean), str(prepared), skip_symbolic_shape=True)
    quantize_static(
        str(prepared),
        str(output),
        Frames(),
        quant_format=QuantFormat.QDQ,
        per_channel=True,
        activation_type=QuantType.QUInt8,
        weight_type=QuantType.QInt8,
        op_types_to_quantize=["Conv", "MaxPool", "Concat", "Resize", "Add", "LeakyRelu"],
        nodes_to_exclude=float_head(lean),
    )


def quantize_openvino(lean: Path, frames: np.ndarray, output: Path) -> None:
    """Step 5: NNCF post-training quantization, saved as IR with dynamic shapes."""
    import nncf
    import openvino

    model = openvino.Core().read_model(str(lean))
    model.reshape({INPUT_NAME: [-1, -1, -1, 3]})
    dataset = nncf.Dataset([frames[i : i + 1] for i in range(len(frames))])
    quantized = nncf.quantize(
        model,
        dataset,
        preset=nncf.QuantizationPreset.MIXED,
        subset_size=len(frames),
        ignored_scope=nncf.IgnoredScope(names=float_head(lean), validate=False),
    )
    openvino.save_model(quantized, str(output), compress_to_fp16=False)


def run_onnxruntime(path: Path, batch: np.ndarray) -> np.ndarray:
    import onnxruntime

    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    return np.asarray(session.run([OUTPUT_NAME], {INPUT_NAME: batch})[0])


def run_openvino(path: Path, batch: np.ndarray) -> np.ndarray:
    import openvino

    core = openvino.Core()
    model = core.read_model(str(path))
    model.reshape({INPUT_NAME: list(batch.shape)})
    compiled = core.compile_model(model, "CPU", {"INFERENCE_NUM_THREADS": 1})
    return np.asarray(compiled.create_infer_request().infer({INPUT_NAME: batch})[OUTPUT_NAME])


def check_parity(ours: np.ndarray, what: str, strict: bool = True) -> tuple[float, float]:
    """The astronaut's best anchor, score and box, against TensorFlow's (step 6): the score and
    largest distance errors; raises when ``strict`` and they exceed the tolerances."""
    expected = np.load(REFERENCE)["person"][0]
    if ours.shape[1:] != expected.shape:
        raise SystemExit(f"{what}: output {ours.shape}, reference {expected.shape}")
    best = int(expected[:, 0].argmax())
    score_error = abs(float(ours[0, best, 0]) - float(expected[best, 0]))
    distance_error = float(np.abs(ours[0, best, 1:] - expected[best, 1:]).max())
    if strict and (score_error > SCORE_ATOL or distance_error > DISTANCE_ATOL):
        raise SystemExit(f"{what}: parity lost (score {score_error:.3f}, distance "
                         f"{distance_error:.3f})")  # fmt: skip
    return score_error, distance_error


def reference_batch() -> np.ndarray:
    reference = np.load(REFERENCE)
    noise = np.random.default_rng(int(reference["noise_seed"])).integers(
        0, 256, reference["astronaut"].shape, dtype=np.uint8
    )
    return np.stack([reference["astronaut"], noise])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out-dir", type=Path, default=WEIGHTS)
    parser.add_argument(
        "--onnxruntime-candidate",
        type=Path,
        default=None,
        help="also write onnxruntime's INT8 graph here (not shipped: measured by "
        "bench.detector.runtimes --candidate)",
    )
    args = parser.parse_args(argv)
    expected = (WEIGHTS / f"{SOURCE.name}.sha256").read_text().split()[0]
    if sha256(SOURCE) != expected:
        raise SystemExit(f"{SOURCE}: sha256 differs from its .sha256 file")
    frames = calibration_frames()
    batch = reference_batch()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        lean = Path(tmp) / "lean.onnx"
        lean_graph(SOURCE, lean)
        exact = float(np.abs(run_onnxruntime(lean, batch) - run_onnxruntime(SOURCE, batch)).max())
        if exact > 1e-3:
            raise SystemExit(f"the lean graph differs from the source by {exact:.2g}")
        print(f"lean graph vs source: largest difference {exact:.2g}")
        xml = Path(tmp) / f"{STEM}.xml"
        quantize_openvino(lean, frames, xml)
        score, distance = check_parity(run_openvino(xml, batch), "openvino")
        print(f"OpenVINO INT8: astronaut score {score:.3f}, distances {distance:.2f} strides off")
        for path in (xml, xml.with_suffix(".bin")):
            target = args.out_dir / path.name
            shutil.copyfile(path, target)
            (args.out_dir / f"{target.name}.sha256").write_text(
                f"{sha256(target)}  {target.name}\n"
            )
            print(f"wrote {target} ({target.stat().st_size / 1e6:.1f} MB), sha256 {sha256(target)}")
        if args.onnxruntime_candidate is not None:
            quantize_onnxruntime(lean, frames, args.onnxruntime_candidate)
            score, distance = check_parity(
                run_onnxruntime(args.onnxruntime_candidate, batch), "onnxruntime", strict=False
            )
            print(f"onnxruntime INT8 (candidate, {args.onnxruntime_candidate}): astronaut score "
                  f"{score:.3f}, distances {distance:.2f} strides off")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
