"""Detector profiles: what a particular person detector makes of the true body, shipped as data.

Why data and not code: every accuracy figure of the project rests on the simulator's boxes, so the
simulator must be exactly as blind as the detector the daemon runs. A profile is a JSON file
(``models/simulate/profiles/<name>.json``, or any path) measured on real-looking frames
(``bench/detector/profiles.py`` turns measurements into profiles and ``bench/detector_profiles.md``
says how each one was measured); changing the detector means shipping its profile, not editing the
noise model. Shipped: ``ideal`` (the simulator's former flat noise, kept for comparison),
``ssdlite`` and ``nanodet`` (the default, :data:`DEFAULT_PROFILE`).

Format ``momloc detector profile v1`` (all keys required but ``input``; unknown keys are refused;
fractions are of the box height unless said otherwise; tables are piecewise linear over their
``height_px`` or ``fraction`` nodes, constant beyond the ends, and a repeated node makes a
step)::

    {"format": "momloc detector profile v1", "name": str, "detector": str, "source": str,
     "reference_height_px": 480,   # image height the height tables were measured at; a camera of
                                   # another height looks its boxes up at h * 480 / its height
                                   # (the detector resizes the whole frame to its input)
     "input": {"height_px": 256, "max_shrink": 3.0},  # optional: the detector's input rows
                                   # grow with taller frames (models.detector.preprocessing.
                                   # input_side), so their boxes count at h * 480 / its height
                                   # * its input rows / the reference frame's input rows
     "min_height_px": 16,          # clipped boxes shorter than this (own pixels) are never found
     "miss": {"height_px": [..], "probability": [..],         # miss probability by box height
              "occlusion": {"fraction": [..], "probability": [..]},   # covered by nearer people
              "truncation": {"fraction": [..], "probability": [..]},  # outside the image
              "correlation_s": 0.5},       # misses persist: Gaussian-copula AR(1), see noise.py
     "occlusion_shrink": {"above": 0.15, "blend": [0.5, 1.0]},  # box moves to the visible part
     "edges": {"height_px": [..], "bottom_bias": [..], "bottom_sigma": [..], "top_bias": [..],
               "top_sigma": [..], "side_sigma": [..],  # bias: detected - true, image y down
               "scale_sigma": 0.05, "scale_clip": 0.15,  # shared scale error about the centre
               "correlation_s": 0.2},                    # AR(1) correlation time of edge errors
     "false_positives": {"per_frame": 0.05,   # mean count per camera and frame (stationary)
                         "persistence_s": 0.5,          # mean lifetime of one false box
                         "height_px": [40, 220], "aspect": [0.3, 0.6],  # size (at reference)
                         "hotspots": 3, "hotspot_share": 0.6,  # furniture-like fixed places
                         "bottom": [0.45, 1.0],  # others: bottom edge in this band of the image
                         "jitter": 0.02},        # per-frame edge jitter of a persisting box
     "keypoints": {"sigma": 0.015, "pixels": 1.0,  # N(0, sigma * h + pixels) px per joint
                   "correlation_s": 0.4,           # AR(1) correlation time of noise and misses
                   "miss": {"height_px": [..], "probability": [..]},  # no pose found in the box
                   "gross": {"head": 0.05, "torso": 0.01, "limbs": 0.2}}}  # joint anywhere in
                                                   # the box (a collapsed pose), per found joint

Example::

    profile = load_profile("ssdlite")        # or load_profile("my_profile.json")
    profile.miss_probability(np.array([80.0]), image_height=480)
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from common.errors import MomlocError
from models.detector.preprocessing import input_side

FORMAT = "momloc detector profile v1"
PROFILE_DIR = Path(__file__).with_name("profiles")
DEFAULT_PROFILE = "nanodet"


@dataclass(frozen=True)
class Table:
    """A piecewise-linear function: ``x`` nodes (non-decreasing; a repeated node is a step)."""

    x: tuple[float, ...]
    y: tuple[float, ...]

    def __call__(self, values: np.ndarray) -> np.ndarray:
        return np.interp(values, self.x, self.y)


@dataclass(frozen=True)
class MissModel:
    """Miss probability by box height, raised by occlusion and truncation; persistence."""

    height: Table
    occlusion: Table
    truncation: Table
    correlation_s: float


@dataclass(frozen=True)
class EdgeModel:
    """Edge errors (fractions of box height) by box height, shared scale error, persistence."""

    height_px: tuple[float, ...]
    bottom_bias: Table
    bottom_sigma: Table
    top_bias: Table
    top_sigma: Table
    side_sigma: Table
    scale_sigma: float
    scale_clip: float
    correlation_s: float


@dataclass(frozen=True)
class FalsePositiveModel:
    """Boxes where nobody is: rate, lifetime, size and place."""

    per_frame: float
    persistence_s: float
    height_px: tuple[float, float]
    aspect: tuple[float, float]
    hotspots: int
    hotspot_share: float
    bottom: tuple[float, float]
    jitter: float


# COCO-17 joints by group for the keypoints' gross-error rates: face, shoulders and hips, limbs.
KEYPOINT_GROUPS = {
    "head": (0, 1, 2, 3, 4),
    "torso": (5, 6, 11, 12),
    "limbs": (7, 8, 9, 10, 13, 14, 15, 16),
}


@dataclass(frozen=True)
class KeypointModel:
    """Pose-estimator noise: pixel noise, whole-pose misses by box height, gross joint errors."""

    sigma: float
    pixels: float
    correlation_s: float
    miss: Table
    gross: tuple[float, ...]  # [17] probability per found joint, COCO order

    @property
    def misses(self) -> bool:
        return any(y > 0 for y in self.miss.y)


@dataclass(frozen=True)
class DetectorInput:
    """How the detector sizes its input: ``height_px`` rows for a reference frame, more for a
    frame taller than ``height_px * max_shrink`` (NanoDet's ``max_shrink`` option)."""

    height_px: int
    max_shrink: float

    def rows(self, image_height: float) -> int:
        return input_side(self.height_px, math.ceil(image_height), self.max_shrink)


@dataclass(frozen=True)
class DetectorProfile:
    """One detector's behaviour, loaded from JSON by :func:`load_profile`."""

    name: str
    detector: str
    source: str
    reference_height_px: float
    min_height_px: float
    miss: MissModel
    shrink_above: float
    shrink_blend: tuple[float, float]
    edges: EdgeModel
    false_positives: FalsePositiveModel
    keypoints: KeypointModel
    input: DetectorInput | None = None  # None: every frame into one fixed input

    @classmethod
    def exact(cls) -> DetectorProfile:
        """No random noise, misses or false positives (truncation and occlusion still apply, as
        in ``ideal``): for debugging and geometry tests."""
        ideal = load_profile("ideal")
        zero = Table((0.0,), (0.0,))
        return dataclasses.replace(
            ideal,
            name="exact",
            miss=dataclasses.replace(ideal.miss, height=zero),
            edges=dataclasses.replace(
                ideal.edges,
                bottom_sigma=zero,
                top_sigma=zero,
                side_sigma=zero,
                scale_sigma=0.0,
            ),
            false_positives=dataclasses.replace(ideal.false_positives, per_frame=0.0),
            keypoints=KeypointModel(0.0, 0.0, 0.0, zero, (0.0,) * 17),
        )

    def reference_height(self, height_px: np.ndarray, image_height: np.ndarray) -> np.ndarray:
        """Box heights as the profile's tables see them: rescaled to the reference frame, and
        back up by as much as the detector's input grows for a taller frame (``input``)."""
        image_height = np.asarray(image_height, float)
        scale = self.reference_height_px / image_height
        if self.input is not None:
            rows = np.vectorize(self.input.rows, otypes=[float])(image_height)
            scale = scale * rows / self.input.rows(self.reference_height_px)
        return height_px * scale

    def miss_probability(
        self,
        height_px: np.ndarray,
        image_height: np.ndarray | float,
        occluded: np.ndarray | float = 0.0,
        truncated: np.ndarray | float = 0.0,
    ) -> np.ndarray:
        """Probability that a person of this (own-pixel) box height is missed.

        The three causes act independently: p = 1 - (1 - p_h)(1 - p_occ)(1 - p_trunc).
        """
        ref = self.reference_height(np.asarray(height_px, float), np.asarray(image_height, float))
        keep = (1.0 - self.miss.height(ref)) * (1.0 - self.miss.occlusion(np.asarray(occluded)))
        keep = keep * (1.0 - self.miss.truncation(np.asarray(truncated)))
        return np.clip(1.0 - keep, 0.0, 1.0)


def available_profiles() -> list[str]:
    """Names of the shipped profiles."""
    return sorted(p.stem for p in PROFILE_DIR.glob("*.json"))


def load_profile(profile: str | Path | DetectorProfile) -> DetectorProfile:
    """A profile by shipped name, or from a ``.json`` path; a loaded profile passes through.

    Raises :class:`MomlocError` naming the file and the key for a missing or malformed profile.
    """
    if isinstance(profile, DetectorProfile):
        return profile
    text = str(profile)
    if text.endswith(".json") or "/" in text or "\\" in text:
        return _load_path(str(Path(text).expanduser().resolve()))
    if text not in available_profiles():
        raise MomlocError(
            f"detector profile '{text}': unknown (available: {', '.join(available_profiles())}; "
            "or give a .json path)"
        )
    return _load_path(str(PROFILE_DIR / f"{text}.json"))


@functools.lru_cache(maxsize=32)
def _load_path(path: str) -> DetectorProfile:
    file = Path(path)
    if not file.is_file():
        raise MomlocError(f"detector profile {file}: no such file")
    try:
        data = json.loads(file.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise MomlocError(f"detector profile {file}: not valid JSON ({error})") from None
    return parse_profile(data, where=str(file))


def parse_profile(data: Any, where: str = "<profile>") -> DetectorProfile:
    """Validate a decoded JSON object; errors name the key, e.g. ``miss.height_px``."""
    r = _Reader(where)
    top = r.keys(data, "", _TOP, optional=("input",))
    if top["format"] != FORMAT:
        raise r.error("format", f"expected '{FORMAT}', got {top['format']!r}")
    miss = r.keys(top["miss"], "miss", _MISS)
    heights = r.nodes(miss["height_px"], "miss.height_px", low=0.0)
    occl = r.keys(miss["occlusion"], "miss.occlusion", ("fraction", "probability"))
    trunc = r.keys(miss["truncation"], "miss.truncation", ("fraction", "probability"))
    shrink = r.keys(top["occlusion_shrink"], "occlusion_shrink", ("above", "blend"))
    edges = r.keys(top["edges"], "edges", _EDGES)
    edge_nodes = r.nodes(edges["height_px"], "edges.height_px", low=0.0)
    fp = r.keys(top["false_positives"], "false_positives", _FALSE)
    kp = r.keys(top["keypoints"], "keypoints", _KEYPOINTS)
    kp_miss = r.keys(kp["miss"], "keypoints.miss", ("height_px", "probability"))
    kp_nodes = r.nodes(kp_miss["height_px"], "keypoints.miss.height_px", low=0.0)
    gross = r.keys(kp["gross"], "keypoints.gross", tuple(KEYPOINT_GROUPS))
    joint_gross = [0.0] * 17
    for group, joints in KEYPOINT_GROUPS.items():
        rate = r.number(gross[group], f"keypoints.gross.{group}", 0.0, 1.0)
        for j in joints:
            joint_gross[j] = rate

    def probs(values: Any, key: str, nodes: tuple[float, ...]) -> Table:
        return Table(nodes, r.values(values, key, len(nodes), 0.0, 1.0))

    def fractions(block: dict, key: str) -> Table:
        nodes = r.nodes(block["fraction"], f"{key}.fraction", 0.0, 1.0)
        return probs(block["probability"], f"{key}.probability", nodes)

    def edge(name: str, low: float, high: float) -> Table:
        return Table(edge_nodes, r.values(edges[name], f"edges.{name}", len(edge_nodes), low, high))

    detector_input = None
    if "input" in top:
        block = r.keys(top["input"], "input", ("height_px", "max_shrink"))
        detector_input = DetectorInput(
            height_px=int(r.number(block["height_px"], "input.height_px", 32, 1e4, whole=True)),
            max_shrink=r.number(block["max_shrink"], "input.max_shrink", 1.0, 100.0),
        )
    return DetectorProfile(
        input=detector_input,
        name=r.text(top["name"], "name"),
        detector=r.text(top["detector"], "detector"),
        source=r.text(top["source"], "source"),
        reference_height_px=r.number(top["reference_height_px"], "reference_height_px", 1.0, 1e5),
        min_height_px=r.number(top["min_height_px"], "min_height_px", 0.0, 1e4),
        miss=MissModel(
            height=probs(miss["probability"], "miss.probability", heights),
            occlusion=fractions(occl, "miss.occlusion"),
            truncation=fractions(trunc, "miss.truncation"),
            correlation_s=r.number(miss["correlation_s"], "miss.correlation_s", 0.0, 60.0),
        ),
        shrink_above=r.number(shrink["above"], "occlusion_shrink.above", 0.0, 1.0),
        shrink_blend=r.span(shrink["blend"], "occlusion_shrink.blend", 0.0, 1.0),
        edges=EdgeModel(
            height_px=edge_nodes,
            bottom_bias=edge("bottom_bias", -1.0, 1.0),
            bottom_sigma=edge("bottom_sigma", 0.0, 1.0),
            top_bias=edge("top_bias", -1.0, 1.0),
            top_sigma=edge("top_sigma", 0.0, 1.0),
            side_sigma=edge("side_sigma", 0.0, 1.0),
            scale_sigma=r.number(edges["scale_sigma"], "edges.scale_sigma", 0.0, 1.0),
            scale_clip=r.number(edges["scale_clip"], "edges.scale_clip", 0.0, 0.9),
            correlation_s=r.number(edges["correlation_s"], "edges.correlation_s", 0.0, 60.0),
        ),
        false_positives=FalsePositiveModel(
            per_frame=r.number(fp["per_frame"], "false_positives.per_frame", 0.0, 10.0),
            persistence_s=r.number(fp["persistence_s"], "false_positives.persistence_s", 0.0, 60),
            height_px=r.span(fp["height_px"], "false_positives.height_px", 1.0, 1e4),
            aspect=r.span(fp["aspect"], "false_positives.aspect", 0.05, 5.0),
            hotspots=int(r.number(fp["hotspots"], "false_positives.hotspots", 0, 32, whole=True)),
            hotspot_share=r.number(fp["hotspot_share"], "false_positives.hotspot_share", 0.0, 1.0),
            bottom=r.span(fp["bottom"], "false_positives.bottom", 0.0, 1.0),
            jitter=r.number(fp["jitter"], "false_positives.jitter", 0.0, 1.0),
        ),
        keypoints=KeypointModel(
            sigma=r.number(kp["sigma"], "keypoints.sigma", 0.0, 1.0),
            pixels=r.number(kp["pixels"], "keypoints.pixels", 0.0, 1e3),
            correlation_s=r.number(kp["correlation_s"], "keypoints.correlation_s", 0.0, 60.0),
            miss=probs(kp_miss["probability"], "keypoints.miss.probability", kp_nodes),
            gross=tuple(joint_gross),
        ),
    )


_TOP = (
    "format", "name", "detector", "source", "reference_height_px", "min_height_px", "miss",
    "occlusion_shrink", "edges", "false_positives", "keypoints",
)  # fmt: skip
_MISS = ("height_px", "probability", "occlusion", "truncation", "correlation_s")
_KEYPOINTS = ("sigma", "pixels", "correlation_s", "miss", "gross")
_EDGES = (
    "height_px", "bottom_bias", "bottom_sigma", "top_bias", "top_sigma", "side_sigma",
    "scale_sigma", "scale_clip", "correlation_s",
)  # fmt: skip
_FALSE = (
    "per_frame", "persistence_s", "height_px", "aspect", "hotspots", "hotspot_share", "bottom",
    "jitter",
)  # fmt: skip


class _Reader:
    """Typed access to the decoded JSON with one-line errors naming the key."""

    def __init__(self, where: str) -> None:
        self.where = where

    def error(self, key: str, problem: str) -> MomlocError:
        return MomlocError(f"detector profile {self.where}: {key or 'top level'}: {problem}")

    def keys(
        self, value: Any, key: str, expected: tuple[str, ...], optional: tuple[str, ...] = ()
    ) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(key, f"expected an object, got {type(value).__name__}")
        prefix = f"{key}." if key else ""
        for name in expected:
            if name not in value:
                raise self.error(f"{prefix}{name}", "missing")
        expected += optional
        for name in value:
            if name not in expected:
                raise self.error(f"{prefix}{name}", f"unknown key (expected {', '.join(expected)})")
        return value

    def text(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.error(key, "expected a non-empty string")
        return value

    def number(self, value: Any, key: str, low: float, high: float, whole: bool = False) -> float:
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not number or not math.isfinite(value):
            raise self.error(key, f"expected a number, got {value!r}")
        if whole and value != int(value):
            raise self.error(key, f"expected a whole number, got {value!r}")
        if not low <= value <= high:
            raise self.error(key, f"{value!r} outside {low:g}..{high:g}")
        return float(value)

    def values(self, value: Any, key: str, count: int, low: float, high: float) -> tuple:
        if not isinstance(value, list) or len(value) != count:
            raise self.error(key, f"expected a list of {count} numbers (one per node)")
        return tuple(self.number(v, f"{key}[{i}]", low, high) for i, v in enumerate(value))

    def nodes(self, value: Any, key: str, low: float, high: float = 1e5) -> tuple:
        if not isinstance(value, list) or not value:
            raise self.error(key, "expected a non-empty list of numbers")
        out = tuple(self.number(v, f"{key}[{i}]", low, high) for i, v in enumerate(value))
        if any(b < a for a, b in itertools.pairwise(out)):
            raise self.error(key, "nodes must be non-decreasing")
        return out

    def span(self, value: Any, key: str, low: float, high: float) -> tuple[float, float]:
        out = self.values(value, key, 2, low, high)
        if out[1] < out[0]:
            raise self.error(key, f"expected [low, high] with low <= high, got {value!r}")
        return out[0], out[1]
