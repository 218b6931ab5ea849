"""The inference runtimes NanoDet's graph runs under: onnxruntime, OpenVINO, ncnn.

Why several: on a small machine the detector's CPU time decides how many frame sets are detected
(the rest carry boxes), and the runtimes differ in CPU time on the same graph; which one is
fastest was measured, not assumed (``bench/results/detector_runtimes.md``,
``bench/detector/runtimes.py``). Every runtime computes the same function: uint8 BGR NHWC batch
in, NanoDet's ``person`` [N, A, 5] out (``models.detector.nanodet``), and the test suite checks
each against TensorFlow's reference outputs.

- **onnxruntime** always works (a base dependency): the fallback.
- **openvino** (``pip install momloc[openvino]``) reads the same ONNX file (FP32) or the INT8
  model ``nanodet_person.int8.xml/.bin`` quantized offline by ``tools/quantize_nanodet.py``
  (NNCF post-training quantization); it compiles one static-shape model per input shape (batch,
  height, width) on first use, because its dynamic-shape path cost more CPU in the measurement.
  INT8 halves the CPU per pair against onnxruntime FP32 and keeps recall within a point; the
  same quantization for onnxruntime lost more than a point and is not shipped (the bench).
- **ncnn** runs ``nanodet_person.ncnn.param/.bin``, converted offline from the ONNX file by
  ``tools/convert_nanodet_ncnn.py``: NanoDet's native runtime. ncnn has no batch: one extractor
  per frame, each normalised by ncnn itself. It uses OpenMP, whose threads spin after each
  layer by default; on the shared 2-core machine that spinning took many times the CPU of the
  inference itself at two threads, so ``OMP_WAIT_POLICY=PASSIVE`` is set before ncnn is first
  imported unless the user set it. Only the shipped model exists for ncnn (a user's ONNX file
  would need the converter).

An :class:`Engine` is a runtime and a precision. ``runtime: auto`` / ``precision: auto`` take the
first engine of :data:`PREFERRED` that fits the settings and whose runtime imports, and log one
line when that is not the first one, so a missing optional runtime is visible but never fatal.
"""

from __future__ import annotations

import importlib.util
import logging
import os
from pathlib import Path
from typing import Literal, NamedTuple, Protocol

import numpy as np

from common.errors import MomlocError
from common.onnx_session import default_threads, open_session
from common.openvino_cpu import CompiledPerShape, read_model

Runtime = Literal["auto", "onnxruntime", "openvino", "ncnn"]
Precision = Literal["auto", "int8", "fp32"]


class Engine(NamedTuple):
    """A runtime and the precision of the shipped model it runs."""

    runtime: str
    precision: str


# Least CPU first at one thread (the daemon's detector beside the pipeline) among the engines
# that keep recall within a point of onnxruntime FP32, by bench/results/detector_runtimes.md;
# onnxruntime FP32 last: it always imports. A user's model runs as it is (FP32, not ncnn).
PREFERRED: tuple[Engine, ...] = (
    Engine("openvino", "int8"),
    Engine("ncnn", "fp32"),
    Engine("openvino", "fp32"),
    Engine("onnxruntime", "fp32"),
)
# How each gets installed: ncnn and onnxruntime are base dependencies, OpenVINO is an extra.
INSTALL = {
    "onnxruntime": "pip install momloc",
    "ncnn": "pip install momloc",
    "openvino": "pip install 'momloc[openvino]'",
}
INPUT_NAME = "images"
OUTPUT_NAME = "person"
MEAN_BGR = (103.53, 116.28, 123.675)
STD_BGR = (57.375, 57.12, 58.395)
log = logging.getLogger(__name__)


class ShippedFiles(NamedTuple):
    """The shipped model's other forms: ncnn's (converted) and OpenVINO's INT8 (quantized)."""

    ncnn_param: Path
    ncnn_weights: Path
    openvino_int8: Path


class NanoDetGraph(Protocol):
    """NanoDet's graph under one runtime."""

    runtime: str
    precision: str

    def run(self, batch: np.ndarray) -> np.ndarray:
        """uint8 BGR [N, H, W, 3] (H, W multiples of 32) → float32 ``person`` [N, A, 5]."""
        ...


def installed(runtime: str) -> bool:
    """Whether ``runtime``'s Python package imports here (each is named as its package)."""
    return importlib.util.find_spec(runtime) is not None


def choose_engine(runtime: Runtime, precision: Precision, user_model: bool) -> Engine:
    """The engine the settings stand for here: the first of :data:`PREFERRED` that matches
    ``runtime`` and ``precision`` (``auto`` matches any) and is installed; else MomlocError."""
    if runtime != "auto" and runtime not in INSTALL:
        raise MomlocError(f"detector runtime {runtime!r} is unknown (choose one of: auto, "
                          f"{', '.join(INSTALL)})")  # fmt: skip
    if user_model and precision == "int8":
        raise MomlocError(
            "detector precision 'int8' is for the shipped NanoDet only (a model_path runs as it "
            "is: precision auto)"
        )
    if user_model and runtime == "ncnn":
        raise MomlocError(
            "detector runtime 'ncnn' runs the shipped NanoDet only (a model_path needs "
            "runtime onnxruntime or openvino)"
        )

    def fits(engine: Engine) -> bool:
        if runtime not in ("auto", engine.runtime) or precision not in ("auto", engine.precision):
            return False
        return not user_model or (engine.precision == "fp32" and engine.runtime != "ncnn")

    candidates = [engine for engine in PREFERRED if fits(engine)]
    if not candidates:
        offered = ", ".join(f"{e.runtime} {e.precision}" for e in PREFERRED)
        raise MomlocError(
            f"detector runtime {runtime!r} has no {precision} model (shipped: {offered})"
        )
    for engine in candidates:
        if installed(engine.runtime):
            if engine != candidates[0]:
                log.info(
                    "detector runtime: %s is not installed, using %s %s (%s for the faster one)",
                    candidates[0].runtime,
                    engine.runtime,
                    engine.precision,
                    INSTALL[candidates[0].runtime],
                )
            return engine
    raise MomlocError(
        f"detector runtime {runtime!r} is not installed ({INSTALL[candidates[0].runtime]}, or "
        "runtime: auto)"
    )


class OnnxRuntimeGraph:
    """The ONNX file under onnxruntime (the project's session settings, common.onnx_session)."""

    runtime = "onnxruntime"
    precision = "fp32"

    def __init__(self, path: Path, threads: int | None) -> None:
        self.path = path
        self.session = open_session(path, threads, what="detector model")
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        ok = (
            len(inputs) == 1
            and inputs[0].name == INPUT_NAME
            and inputs[0].type == "tensor(uint8)"
            and len(inputs[0].shape) == 4
            and any(o.name == OUTPUT_NAME for o in outputs)
        )
        if not ok:
            got = ", ".join(f"{i.name} {i.type} {i.shape}" for i in inputs)
            raise MomlocError(
                f"detector model {path}: not a NanoDet person model (expected uint8 "
                f"input {INPUT_NAME!r} [N, H, W, 3] and output {OUTPUT_NAME!r}; got {got})"
            )

    def run(self, batch: np.ndarray) -> np.ndarray:
        (raw,) = self.session.run([OUTPUT_NAME], {INPUT_NAME: batch})
        return np.asarray(raw)


class OpenVinoGraph:
    """The ONNX file (FP32) or the INT8 IR under OpenVINO's CPU plugin, one compiled model per
    input shape."""

    runtime = "openvino"

    def __init__(self, path: Path, threads: int | None, precision: str = "fp32") -> None:
        self.precision = precision
        self.path = path
        model = read_model(path, "detector model")
        names = [port.get_any_name() for port in model.inputs]
        outputs = {name for port in model.outputs for name in port.get_names()}
        if names != [INPUT_NAME] or OUTPUT_NAME not in outputs:
            raise MomlocError(
                f"detector model {path}: not a NanoDet person model (inputs {names}, expected "
                f"[{INPUT_NAME!r}] and output {OUTPUT_NAME!r})"
            )
        self._compiled = CompiledPerShape(model, INPUT_NAME, threads)

    def run(self, batch: np.ndarray) -> np.ndarray:
        (raw,) = self._compiled.infer(batch, (OUTPUT_NAME,))
        return raw


class NcnnGraph:
    """The converted ncnn files (``tools/convert_nanodet_ncnn.py``), one extractor per frame."""

    runtime = "ncnn"
    precision = "fp32"

    def __init__(self, param: Path, weights: Path, threads: int | None) -> None:
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before libgomp loads: see above
        import ncnn

        for path in (param, weights):
            if not path.is_file():
                raise MomlocError(f"detector model {path}: file not found")
        self.path = weights
        self._ncnn = ncnn
        self._net = ncnn.Net()
        self._net.opt.num_threads = default_threads(threads)
        self._net.opt.openmp_blocktime = 0
        if self._net.load_param(str(param)) != 0 or self._net.load_model(str(weights)) != 0:
            raise MomlocError(f"detector model {param}: not loadable by ncnn")
        self._scale = [1.0 / s for s in STD_BGR]

    def run(self, batch: np.ndarray) -> np.ndarray:
        ncnn = self._ncnn
        outputs = []
        for image in batch:
            height, width = image.shape[:2]
            mat = ncnn.Mat.from_pixels(image, ncnn.Mat.PixelType.PIXEL_BGR, width, height)
            mat.substract_mean_normalize(MEAN_BGR, self._scale)
            with self._net.create_extractor() as extractor:
                extractor.input("in0", mat)
                status, out = extractor.extract("out0")
                if status != 0:
                    raise MomlocError(f"detector model {self.path}: ncnn failed ({status})")
                outputs.append(np.array(out))
        return np.stack(outputs)


def open_graph(
    runtime: Runtime,
    precision: Precision,
    onnx_path: Path,
    shipped: ShippedFiles | None,
    threads: int | None,
) -> NanoDetGraph:
    """NanoDet's graph under the chosen engine; ``shipped`` is None for a user's model."""
    engine = choose_engine(runtime, precision, user_model=shipped is None)
    if shipped is not None and engine == ("ncnn", "fp32"):
        return NcnnGraph(shipped.ncnn_param, shipped.ncnn_weights, threads)
    if shipped is not None and engine == ("openvino", "int8"):
        return OpenVinoGraph(shipped.openvino_int8, threads, "int8")
    if engine.runtime == "openvino":
        return OpenVinoGraph(onnx_path, threads)
    return OnnxRuntimeGraph(onnx_path, threads)
