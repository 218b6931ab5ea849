"""Loaders for the real multi-camera data sets in ``../shared/data`` (evaluation only).

The data never enters the repository: the ``bench.real_*`` benchmarks read it from ``--data``
(default ``../shared/data`` next to the checkout) and print one line and exit 0 when their folder
is absent, so the project stays runnable without it.

Wildtrack and MultiviewX share one layout (MultiviewX copied Wildtrack's): OpenCV XML
calibrations (``calibrations/extrinsic/extr_<cam>.xml`` with a Rodrigues ``rvec`` and ``tvec``,
``calibrations/intrinsic*/intr_<cam>.xml`` with ``camera_matrix``), and
``annotations_positions/<frame>.json`` with each person's ``positionID`` on a floor grid. Their
"boxes" are projected cylinders, not person boxes (``../shared/data/README.md``): only the
geometry and the positions are used here. Wildtrack's extrinsics are in centimetres, its grid in
metres; everything here is metres.

The real cameras become simulator cameras through :class:`CalibratedSpec`, a
:class:`~models.simulate.scene.CameraSpec` that returns the calibrated camera instead of a look-at
one, so a :class:`~models.simulate.Scene` on the real geometry draws, detects and noises people
with the product's own simulator.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from models.simulate.camera import PinholeCamera
from models.simulate.scene import CameraSpec

DEFAULT_DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def data_folder(data: Path, name: str) -> Path | None:
    """``data/name`` when it exists, else None (after printing the one skip line)."""
    folder = Path(data) / name
    if folder.is_dir():
        return folder
    print(f"bench.real.{name}: {folder} not found; skipped (see ../shared/data/README.md)")
    return None


def opencv_values(path: Path, tag: str) -> np.ndarray:
    """The numbers of element ``tag`` of an OpenCV XML file (its ``<data>`` child if it has one,
    as ``cv::FileStorage`` writes matrices, else its own text, as Wildtrack's extrinsics are)."""
    node = ET.parse(path).getroot().find(tag)
    if node is None:
        raise ValueError(f"{path}: no <{tag}>")
    data = node.find("data")
    text = (data if data is not None else node).text or ""
    return np.array([float(v) for v in text.split()], dtype=np.float64)


def rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rotation matrix of an axis-angle vector (OpenCV's ``Rodrigues``), numpy only."""
    rvec = np.asarray(rvec, dtype=np.float64).reshape(3)
    angle = float(np.linalg.norm(rvec))
    if angle < 1e-12:
        return np.eye(3)
    k = rvec / angle
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross


@dataclass(frozen=True)
class Calibration:
    """One real camera: intrinsics ``K``, world→camera ``R``, ``t`` (metres), image (w, h)."""

    name: str
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]

    def camera(self) -> PinholeCamera:
        return PinholeCamera(self.K, self.R, self.t, self.image_size)

    def facing(self, points: np.ndarray) -> Calibration:
        """The same projection with the sign of [R | t] chosen so that ``points`` [N, 3] (the
        annotated floor) lie in front of the camera. MultiviewX's calibration (fitted to a
        Unity scene) puts them at negative depth: pixels are unchanged by the flip, but the
        simulator, like any camera model, drops points behind the camera."""
        if np.median(self.project(points)[1]) >= 0:
            return self
        return Calibration(self.name, self.K, -self.R, -self.t, self.image_size)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points [..., 3] → pixels [..., 2] and depth [...] (metres along the axis)."""
        cam = np.einsum("ij,...j->...i", self.R, np.asarray(points, float)) + self.t
        pixels = np.einsum("ij,...j->...i", self.K, cam)
        with np.errstate(divide="ignore", invalid="ignore"):
            return pixels[..., :2] / pixels[..., 2:3], cam[..., 2]


@dataclass(frozen=True)
class CalibratedSpec(CameraSpec):
    """A simulator camera hung where a real one is: :meth:`camera` returns the calibrated one
    (``position`` is its centre, for anything that reads it)."""

    calibration: Calibration | None = field(default=None, compare=False)

    @classmethod
    def of(cls, calibration: Calibration) -> CalibratedSpec:
        centre = -calibration.R.T @ calibration.t
        ahead = centre + calibration.R[2]
        return cls(
            position=(float(centre[0]), float(centre[1]), float(centre[2])),
            target=(float(ahead[0]), float(ahead[1]), float(ahead[2])),
            image_size=calibration.image_size,
            calibration=calibration,
        )

    def camera(self) -> PinholeCamera:
        assert self.calibration is not None
        return self.calibration.camera()


def load_calibrations(
    folder: Path,
    names: list[str],
    intrinsic: str,
    image_size: tuple[int, int],
    metres_per_unit: float = 1.0,
) -> list[Calibration]:
    """Cameras ``names`` of a Wildtrack-layout folder; ``intrinsic`` is the intrinsics folder
    (Wildtrack: ``intrinsic_zero``, for its undistorted images); the data's lens distortion is
    zero (Wildtrack's undistorted set) or below 1e-5 (MultiviewX), so it is left out."""
    out = []
    for name in names:
        extrinsic = folder / "calibrations" / "extrinsic" / f"extr_{name}.xml"
        intr = folder / "calibrations" / intrinsic / f"intr_{name}.xml"
        R = rodrigues(opencv_values(extrinsic, "rvec"))
        t = opencv_values(extrinsic, "tvec") * metres_per_unit
        K = opencv_values(intr, "camera_matrix").reshape(3, 3)
        out.append(Calibration(name, K, R, t, image_size))
    return out


@dataclass(frozen=True)
class FloorGrid:
    """The data set's floor grid: ``positionID`` = row * ``columns`` + column, ``step`` metres
    apart, column 0 / row 0 at ``origin``."""

    origin: tuple[float, float]
    step: float
    columns: int

    def position(self, ids: np.ndarray) -> np.ndarray:
        ids = np.asarray(ids, dtype=np.int64)
        x = self.origin[0] + self.step * (ids % self.columns)
        y = self.origin[1] + self.step * (ids // self.columns)
        return np.stack([x, y], axis=-1).astype(np.float64)


@dataclass(frozen=True)
class FramePositions:
    """Everyone annotated in one frame: ``ids`` [P] person ids, ``xy`` [P, 2] floor metres."""

    frame: int
    ids: np.ndarray
    xy: np.ndarray


def load_positions(folder: Path, grid: FloorGrid) -> list[FramePositions]:
    """Every ``annotations_positions/*.json`` in name order (the frame is the name's number)."""
    out = []
    for path in sorted((folder / "annotations_positions").glob("*.json")):
        people = json.loads(path.read_text())
        ids = np.array([p["personID"] for p in people], dtype=np.int64)
        where = np.array([p["positionID"] for p in people], dtype=np.int64)
        out.append(FramePositions(int(path.stem), ids, grid.position(where).reshape(-1, 2)))
    return out
