"""NanoDet under every inference runtime: parity with TensorFlow, the same boxes, the choice.

Each engine (runtime and precision) must reproduce the TensorFlow outputs of the original TF.js
graph stored by ``tools/convert_nanodet.py`` in ``nanodet_reference.npz`` (a fixed batch at the
native 416×416): FP32 to float tolerance, the INT8 model (``tools/quantize_nanodet.py``) at the
decisive anchor. An engine whose runtime is not installed is skipped with the reason;
onnxruntime always is.
"""

from __future__ import annotations

import hashlib
import logging

import numpy as np
import pytest

from common.errors import MomlocError
from models.detector import create_detector, runtimes
from models.detector.nanodet import DEFAULT_MODEL, SHIPPED_PATHS, WEIGHTS_DIR, NanoDetDetector
from models.detector.preprocessing import box_iou
from models.detector.validation import person_frame

# ncnn stores the weights as float16 (tools/convert_nanodet_ncnn.py), hence its looser tolerance.
TOLERANCE = {"onnxruntime": (1e-4, 1e-3), "openvino": (1e-4, 1e-3), "ncnn": (5e-4, 3e-3)}
ENGINES = [
    pytest.param(
        engine,
        id=f"{engine.runtime}-{engine.precision}",
        marks=pytest.mark.skipif(
            not runtimes.installed(engine.runtime),
            reason=f"{engine.runtime} is not installed here ({runtimes.INSTALL[engine.runtime]})",
        ),
    )
    for engine in runtimes.PREFERRED
]
FP32 = [p for p, e in zip(ENGINES, runtimes.PREFERRED, strict=True) if e.precision == "fp32"]
INT8 = [p for p, e in zip(ENGINES, runtimes.PREFERRED, strict=True) if e.precision == "int8"]


def reference_batch() -> tuple[np.ndarray, np.ndarray]:
    reference = np.load(WEIGHTS_DIR / "nanodet_reference.npz")
    noise = np.random.default_rng(int(reference["noise_seed"])).integers(
        0, 256, reference["astronaut"].shape, dtype=np.uint8
    )
    return np.stack([reference["astronaut"], noise]), reference["person"]


@pytest.mark.parametrize("engine", FP32)
def test_every_fp32_runtime_reproduces_the_tensorflow_graph(engine):
    runtime = engine.runtime
    detector = _nanodet(runtime=runtime, precision="fp32", threads=1)
    assert (detector.graph.runtime, detector.graph.precision) == engine
    assert f"{runtime} fp32" in detector.describe()
    batch, expected = reference_batch()
    ours = detector.graph.run(batch)
    assert ours.shape == expected.shape == (2, 52 * 52 + 26 * 26 + 13 * 13, 5)
    score_atol, distance_atol = TOLERANCE[runtime]
    np.testing.assert_allclose(ours[..., 0], expected[..., 0], atol=score_atol)
    confident = expected[..., 0] > 0.05
    np.testing.assert_allclose(
        ours[..., 1:][confident], expected[..., 1:][confident], atol=distance_atol
    )
    assert expected[0, :, 0].max() > 0.7  # the astronaut is found by the original graph


@pytest.mark.parametrize("engine", INT8)
def test_the_int8_model_keeps_the_decisive_outputs_of_the_tensorflow_graph(engine):
    """8-bit activations cannot reproduce float scores to 1e-4: the astronaut's best anchor
    keeps its score within 0.08 and its box edges within 1.5 strides (the tolerances of
    tools/quantize_nanodet.py), nothing passes the shipped threshold in the noise frame, and no
    other anchor overtakes."""
    detector = _nanodet(runtime=engine.runtime, precision="int8", threads=1)
    assert (detector.graph.runtime, detector.graph.precision) == engine
    assert f"{engine.runtime} int8" in detector.describe()
    batch, expected = reference_batch()
    ours = detector.graph.run(batch)
    assert ours.shape == expected.shape
    best = int(expected[0, :, 0].argmax())
    assert abs(ours[0, best, 0] - expected[0, best, 0]) < 0.08
    assert np.abs(ours[0, best, 1:] - expected[0, best, 1:]).max() < 1.5
    assert ours[0, :, 0].max() - ours[0, best, 0] < 0.05
    assert ours[1, :, 0].max() < 0.4  # the shipped threshold: nothing found in noise


@pytest.mark.parametrize("engine", ENGINES)
def test_every_engine_finds_the_same_people_at_two_sizes(engine):
    """A pair of frames at the default input and a larger one: the engines must agree on the
    boxes (OpenVINO compiles one model per shape, ncnn reshapes per frame); INT8 within the
    rounding of 8-bit activations (its scores on these drawn people ran up to 0.15 higher)."""
    frames = [
        person_frame("camera", 300, anchor=(0.2, 0.5))[0],
        person_frame("camera", 200, anchor=(0.8, 0.6))[0],
    ]
    min_iou, score_atol = (0.97, 2e-3) if engine.precision == "fp32" else (0.85, 0.2)
    reference = _nanodet(runtime="onnxruntime", threads=1)
    ours = _nanodet(runtime=engine.runtime, precision=engine.precision, threads=1)
    for size in ((320, 256), (416, 320)):
        for want, got in zip(
            reference.resized(size).detect(frames), ours.resized(size).detect(frames), strict=True
        ):
            assert len(want) == len(got) >= 1
            assert box_iou(want.boxes, got.boxes).max(axis=1).min() > min_iou
            np.testing.assert_allclose(want.scores, got.scores, atol=score_atol)


def test_shipped_files_match_their_checksums():
    for path in SHIPPED_PATHS:
        expected, name = (WEIGHTS_DIR / f"{path.name}.sha256").read_text().split()
        assert name == path.name
        assert hashlib.sha256(path.read_bytes()).hexdigest() == expected


def test_auto_takes_the_first_installed_and_says_when_it_falls_back(monkeypatch, caplog):
    monkeypatch.setattr(runtimes, "installed", lambda name: True)
    assert runtimes.choose_engine("auto", "auto", user_model=False) == runtimes.PREFERRED[0]
    assert runtimes.choose_engine("auto", "fp32", user_model=False) == ("ncnn", "fp32")
    assert runtimes.choose_engine("openvino", "auto", user_model=False) == ("openvino", "int8")
    assert runtimes.choose_engine("auto", "auto", user_model=True) == ("openvino", "fp32")
    monkeypatch.setattr(runtimes, "installed", lambda name: name == "onnxruntime")
    with caplog.at_level(logging.INFO, logger=runtimes.__name__):
        assert runtimes.choose_engine("auto", "auto", user_model=False) == ("onnxruntime", "fp32")
    assert f"{runtimes.PREFERRED[0].runtime} is not installed, using onnxruntime" in caplog.text
    detector = _nanodet(threads=1)
    assert detector.graph.runtime == "onnxruntime"


def test_an_engine_that_cannot_serve_fails_with_one_line(monkeypatch, tmp_path):
    with pytest.raises(MomlocError, match="runs the shipped NanoDet only"):
        runtimes.choose_engine("ncnn", "auto", user_model=True)
    with pytest.raises(MomlocError, match="'int8' is for the shipped NanoDet only"):
        runtimes.choose_engine("auto", "int8", user_model=True)
    with pytest.raises(MomlocError, match="'onnxruntime' has no int8 model"):
        runtimes.choose_engine("onnxruntime", "int8", user_model=False)
    assert runtimes.choose_engine("auto", "auto", user_model=True).runtime != "ncnn"
    monkeypatch.setattr(runtimes, "installed", lambda name: name == "onnxruntime")
    with pytest.raises(MomlocError, match=r"'openvino' is not installed \(pip install 'momloc\["):
        create_detector("nanodet", runtime="openvino")
    with pytest.raises(MomlocError, match=r"'auto' is not installed .*momloc\[openvino\]"):
        runtimes.choose_engine("auto", "int8", user_model=False)
    with pytest.raises(MomlocError, match="unknown"):
        runtimes.choose_engine("tensorrt", "auto", user_model=False)  # type: ignore[arg-type]
    user = _nanodet(model_path=DEFAULT_MODEL, runtime="onnxruntime")
    assert user.graph.runtime == "onnxruntime"


def _nanodet(**options: object) -> NanoDetDetector:
    """The registry's NanoDet (``create_detector``), as its own type."""
    detector = create_detector("nanodet", **options)
    assert isinstance(detector, NanoDetDetector)
    return detector
