"""NanoDet under every inference runtime: parity with TensorFlow, the same boxes, the choice.

Each runtime must reproduce the TensorFlow outputs of the original TF.js graph stored by
``tools/convert_nanodet.py`` in ``nanodet_reference.npz`` (a fixed batch at the native 416×416).
A runtime that is not installed is skipped with the reason; onnxruntime always is.
"""

from __future__ import annotations

import hashlib
import logging

import numpy as np
import pytest

from common.errors import MomlocError
from models.detector import create_detector, runtimes
from models.detector.nanodet import DEFAULT_MODEL, NCNN_FILES, WEIGHTS_DIR, NanoDetDetector
from models.detector.preprocessing import box_iou
from models.detector.validation import person_frame

# ncnn stores the weights as float16 (tools/convert_nanodet_ncnn.py), hence its looser tolerance.
TOLERANCE = {"onnxruntime": (1e-4, 1e-3), "openvino": (1e-4, 1e-3), "ncnn": (5e-4, 3e-3)}
RUNTIMES = [
    pytest.param(
        name,
        marks=pytest.mark.skipif(
            not runtimes.installed(name),
            reason=f"{name} is not installed here ({runtimes.INSTALL[name]})",
        ),
    )
    for name in ("onnxruntime", "openvino", "ncnn")
]


def reference_batch() -> tuple[np.ndarray, np.ndarray]:
    reference = np.load(WEIGHTS_DIR / "nanodet_reference.npz")
    noise = np.random.default_rng(int(reference["noise_seed"])).integers(
        0, 256, reference["astronaut"].shape, dtype=np.uint8
    )
    return np.stack([reference["astronaut"], noise]), reference["person"]


@pytest.mark.parametrize("runtime", RUNTIMES)
def test_every_runtime_reproduces_the_tensorflow_graph(runtime):
    detector = _nanodet(runtime=runtime, threads=1)
    assert detector.graph.runtime == runtime and runtime in detector.describe()
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


@pytest.mark.parametrize("runtime", RUNTIMES)
def test_every_runtime_finds_the_same_people_at_two_sizes(runtime):
    """A pair of frames at the default input and a larger one: the runtimes must agree on the
    boxes (OpenVINO compiles one model per shape, ncnn reshapes per frame)."""
    frames = [
        person_frame("camera", 300, anchor=(0.2, 0.5))[0],
        person_frame("camera", 200, anchor=(0.8, 0.6))[0],
    ]
    reference = _nanodet(runtime="onnxruntime", threads=1)
    ours = _nanodet(runtime=runtime, threads=1)
    for size in ((320, 256), (416, 320)):
        for want, got in zip(
            reference.resized(size).detect(frames), ours.resized(size).detect(frames), strict=True
        ):
            assert len(want) == len(got) >= 1
            assert box_iou(want.boxes, got.boxes).max(axis=1).min() > 0.97
            np.testing.assert_allclose(want.scores, got.scores, atol=2e-3)


def test_shipped_ncnn_files_match_their_checksums():
    for path in NCNN_FILES:
        expected, name = (WEIGHTS_DIR / f"{path.name}.sha256").read_text().split()
        assert name == path.name
        assert hashlib.sha256(path.read_bytes()).hexdigest() == expected


def test_auto_takes_the_first_installed_and_says_when_it_falls_back(monkeypatch, caplog):
    monkeypatch.setattr(runtimes, "installed", lambda name: True)
    assert runtimes.choose_runtime("auto", user_model=False) == runtimes.PREFERRED[0]
    monkeypatch.setattr(runtimes, "installed", lambda name: name == "onnxruntime")
    with caplog.at_level(logging.INFO, logger=runtimes.__name__):
        assert runtimes.choose_runtime("auto", user_model=False) == "onnxruntime"
    assert f"{runtimes.PREFERRED[0]} is not installed, using onnxruntime" in caplog.text
    detector = _nanodet(threads=1)
    assert detector.graph.runtime == "onnxruntime"


def test_a_runtime_that_cannot_serve_fails_with_one_line(monkeypatch, tmp_path):
    with pytest.raises(MomlocError, match="runs the shipped NanoDet only"):
        runtimes.choose_runtime("ncnn", user_model=True)
    assert runtimes.choose_runtime("auto", user_model=True) != "ncnn"
    monkeypatch.setattr(runtimes, "installed", lambda name: name == "onnxruntime")
    with pytest.raises(MomlocError, match=r"'openvino' is not installed \(pip install 'momloc\["):
        create_detector("nanodet", runtime="openvino")
    with pytest.raises(MomlocError, match="unknown"):
        runtimes.choose_runtime("tensorrt", user_model=False)  # type: ignore[arg-type]
    user = _nanodet(model_path=DEFAULT_MODEL, runtime="onnxruntime")
    assert user.graph.runtime == "onnxruntime"


def _nanodet(**options: object) -> NanoDetDetector:
    """The registry's NanoDet (``create_detector``), as its own type."""
    detector = create_detector("nanodet", **options)
    assert isinstance(detector, NanoDetDetector)
    return detector
