"""A synthetic room: cameras, walking people and what each camera's detector reports, per frame.

``Scene(config, seed)`` is deterministic: the walking paths come from one generator seeded with
``[seed, 0]``, the appearance (clothes) from ``[seed, 2]``, and the detector noise of frames
``64 b .. 64 b + 63`` from ``[seed, 1, b]`` (plus ``[seed, 3, b]`` and ``[seed, 3, b + 1]`` for
the temporally correlated edge errors, ``[seed, 6, b]`` and ``[seed, 6, b + 1]`` for the
persistent misses, ``[seed, 9, b]`` and ``[seed, 9, b + 1]`` for the keypoint noise and
``[seed, 10, b]`` and ``[seed, 10, b + 1]`` for the pose-miss latents when the profile's keypoints
have a correlation time (without one both come from ``[seed, 1, b]``), ``[seed, 4, b]``,
``[seed, 4, b + 1]`` and ``[seed, 8, b]`` for the false positives, ``[seed, 5]`` for their fixed
places; ``[seed, 11]`` and ``[seed, 12, s]`` for the people outside the set-up area, see
:mod:`models.simulate.outside`; ``[seed, 13, i]`` for the height of scripted person ``i``), so
``observe(i)`` returns the same arrays whatever was observed before, and ``simulate`` (which
observes whole blocks at once) agrees with it.
``[seed, 1, b]`` is drawn from in a fixed order, boxes first and the keypoints' gross errors
last, so the boxes do not depend on the keypoint model.

How blind the detector is comes from ``SceneConfig.detector_profile`` (a shipped profile's name,
a JSON path or a loaded :class:`~models.simulate.profile.DetectorProfile`; default the shipped
detector's, ``nanodet``): see :mod:`models.simulate.profile` and :mod:`models.simulate.noise`.

Camera perturbations model a camera that was bumped at some frame: from ``start_frame`` on, that
camera's image is shifted by (dx, dy) pixels and rolled by ``roll_deg`` about the principal point.
``projection_matrices()`` keeps returning the true matrices of the *unperturbed* cameras (what a
calibration made before the bump would hold); ``projection_matrices(frame)`` gives the ones in
force at that frame.
"""

from __future__ import annotations

import itertools
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from common.errors import MomlocError
from models.simulate import false_positives
from models.simulate.camera import NEAR, PinholeCamera, project_points
from models.simulate.furniture import Occluders
from models.simulate.noise import KeypointDraws, correlated_normals, detect
from models.simulate.observation import OBSERVED, FrameObservation
from models.simulate.outside import Placed, Together, outside_walkers
from models.simulate.people import REPULSION, SEPARATION, Walkers, Walking
from models.simulate.postures import CODES
from models.simulate.profile import DEFAULT_PROFILE, DetectorProfile, load_profile
from models.simulate.room import Furniture
from models.simulate.script import ScriptedWalker, Segment
from models.simulate.skeleton import HEAD, MID_HIP, RADII, body_points

if TYPE_CHECKING:  # imported when the first frame is drawn (it needs cv2)
    from models.simulate.render import Renderer

BLOCK = 64  # frames observed (and noised) together
MAX_CAMERAS = 9


@dataclass(frozen=True)
class CameraSpec:
    """Where a camera hangs and what it looks like (world metres, z up)."""

    position: tuple[float, float, float]
    target: tuple[float, float, float]
    hfov_deg: float = 65.0
    image_size: tuple[int, int] = (640, 480)
    distortion: tuple[float, float] = (0.0, 0.0)

    def camera(self) -> PinholeCamera:
        return PinholeCamera.look_at(
            self.position, self.target, self.hfov_deg, self.image_size, self.distortion
        )


@dataclass(frozen=True)
class Perturbation:
    """Camera ``camera`` bumped at ``start_frame``: image shift (dx, dy) px and roll in degrees."""

    camera: int
    start_frame: int = 0
    dx: float = 0.0
    dy: float = 0.0
    roll_deg: float = 0.0


@dataclass(frozen=True)
class SceneConfig:
    """A room of ``room`` = (width, depth) metres seen by ``cameras`` with ``people`` walking."""

    name: str
    room: tuple[float, float]
    cameras: tuple[CameraSpec, ...]
    people: int = 3
    fps: float = 15.0
    detector_profile: str | DetectorProfile = DEFAULT_PROFILE
    perturbations: tuple[Perturbation, ...] = ()
    wall_height: float = 2.8
    outdoor: bool = False  # rendering only: open ground and sky instead of walls and ceiling
    # The set-up area (xmin, xmax, ymin, ymax metres) where the ``people`` walk and are labelled;
    # None: the whole room. ``outside_people`` more walk in view beyond it, in the room (grown by
    # ``outside_band`` metres past its walls) minus the area: see models.simulate.outside.
    area: tuple[float, float, float, float] | None = None
    outside_people: int = 0
    outside_band: float = 0.0
    outside_region: tuple[float, float, float, float] | None = None  # None: room + band
    outside_posture: str = "standing"  # what the outside people hold (models.simulate.postures)
    # How the ``people`` keep apart: pushed by ``repulsion`` of the overlap per step within
    # ``separation`` metres (models.simulate.people).
    separation: float = SEPARATION
    repulsion: float = REPULSION
    # Furniture standing in the room (sofas, tables, desks): drawn, and it hides the parts of
    # people behind it from the cameras and their detector (models.simulate.furniture).
    furniture: tuple[Furniture, ...] = ()
    # People who follow a script (sit on the sofa, crouch, fall; room metres), labelled after
    # the ``people`` random walkers (who may then be 0).
    scripts: tuple[tuple[Segment, ...], ...] = ()

    def __post_init__(self) -> None:
        if not 1 <= len(self.cameras) <= MAX_CAMERAS:
            raise MomlocError(f"scene '{self.name}': {len(self.cameras)} cameras, expected 1 to 9")
        if min(self.room) <= 1.0:
            raise MomlocError(f"scene '{self.name}': room {self.room} must be over 1 m each way")
        if self.people < (0 if self.scripts else 1):
            raise MomlocError(f"scene '{self.name}': people must be at least 1, got {self.people}")
        if not 1.0 <= self.fps <= 240.0:
            raise MomlocError(f"scene '{self.name}': fps {self.fps} outside 1..240")
        for p in self.perturbations:
            if not 0 <= p.camera < len(self.cameras):
                raise MomlocError(f"scene '{self.name}': perturbation of unknown camera {p.camera}")
        if self.separation < 0 or not 0 <= self.repulsion <= 0.5:
            raise MomlocError(
                f"scene '{self.name}': separation must be >= 0 and repulsion in 0..0.5, got "
                f"{self.separation}, {self.repulsion}"
            )
        if self.outside_posture not in CODES:
            raise MomlocError(
                f"scene '{self.name}': outside posture '{self.outside_posture}' is not one of "
                f"{', '.join(CODES)}"
            )
        if self.outside_people < 0 or self.outside_band < 0:
            raise MomlocError(f"scene '{self.name}': outside people and band must be >= 0")
        if self.area is not None:
            x0, x1, y0, y1 = self.area
            inside = x0 >= 0 and y0 >= 0 and x1 <= self.room[0] and y1 <= self.room[1]
            if not (inside and x1 - x0 >= 1.0 and y1 - y0 >= 1.0):
                raise MomlocError(
                    f"scene '{self.name}': area {self.area} must lie in the room {self.room} "
                    "and be at least 1 m each way"
                )

    @property
    def setup_area(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) where the labelled people walk: ``area`` or the room."""
        return self.area if self.area is not None else (0.0, self.room[0], 0.0, self.room[1])

    @property
    def num_cameras(self) -> int:
        return len(self.cameras)


class Scene:
    """Cameras, people and detections of a :class:`SceneConfig`, reproducible from ``seed``."""

    def __init__(self, config: SceneConfig, seed: int = 0) -> None:
        self.config = config
        self.seed = int(seed)
        self.cameras = [spec.camera() for spec in config.cameras]
        self.profile = load_profile(config.detector_profile)
        self._fp_places = false_positives.hotspots(
            self.profile, self.image_sizes, np.random.default_rng([self.seed, 5])
        )
        walkers = Walkers(
            config.room if config.area is None else (config.area[1] - config.area[0],
                                                     config.area[3] - config.area[2]),
            config.people, config.fps, np.random.default_rng([self.seed, 0]),
            config.separation, config.repulsion,
        )  # fmt: skip
        self.walkers: Walking = (
            walkers if config.area is None else Placed(walkers, (config.area[0], config.area[2]))
        )
        if config.scripts:
            scripted = [
                ScriptedWalker(list(script), config.fps, np.random.default_rng([self.seed, 13, i]))
                for i, script in enumerate(config.scripts)
            ]
            groups: list[Walking] = [self.walkers] if config.people else []
            self.walkers = Together([*groups, *scripted])
        self.occluders = Occluders(config.furniture)
        self.outsiders: Walking | None = None
        if config.outside_people:
            self.outsiders = outside_walkers(
                config.room, config.setup_area, config.outside_band, config.outside_people,
                config.fps, self.seed, config.outside_region, config.outside_posture,
            )  # fmt: skip
        self._perturbed: dict[int, list[tuple[int, PinholeCamera]]] = {}
        for p in sorted(config.perturbations, key=lambda q: q.start_frame):
            base = self.cameras[p.camera]
            self._perturbed.setdefault(p.camera, []).append(
                (p.start_frame, base.perturbed(p.dx, p.dy, p.roll_deg))
            )
        self._blocks: OrderedDict[int, dict[str, np.ndarray]] = OrderedDict()
        self._renderer: Renderer | None = None
        # The body points of the last rendered frame: every camera of a frame set draws the same
        # bodies, so they are posed once per frame, not once per camera.
        self._posed: tuple[int, np.ndarray] | None = None
        # Camera workers of a live demo may share one scene: the walker cache and block cache
        # are filled lazily, so those fills are serialised.
        self._lock = threading.RLock()

    @property
    def fps(self) -> float:
        return self.config.fps

    @property
    def num_cameras(self) -> int:
        return len(self.cameras)

    @property
    def image_sizes(self) -> np.ndarray:
        """[K, 2] int32 width, height."""
        return np.array([c.image_size for c in self.cameras], dtype=np.int32)

    def floor_extent(self) -> dict[str, float]:
        """The room's floor in metres (the map's extent for a synthetic scene)."""
        width, depth = self.config.room
        return {"xmin": 0.0, "xmax": float(width), "ymin": 0.0, "ymax": float(depth)}

    def cameras_at(self, frame_index: int) -> list[PinholeCamera]:
        """The cameras in force at a frame (perturbed ones after their bump)."""
        out = list(self.cameras)
        for k, events in self._perturbed.items():
            for start, camera in events:
                if frame_index >= start:
                    out[k] = camera
        return out

    def projection_matrices(self, frame_index: int | None = None) -> np.ndarray:
        """[K, 3, 4]: the true unperturbed matrices, or those in force at ``frame_index``."""
        cams = self.cameras if frame_index is None else self.cameras_at(frame_index)
        return np.stack([c.projection_matrix for c in cams])

    def observe(self, frame_index: int) -> FrameObservation:
        """Ground truth and detections of one frame."""
        if frame_index < 0:
            raise MomlocError(f"frame index must be >= 0, got {frame_index}")
        block = self.observe_block(frame_index // BLOCK)
        i = frame_index % BLOCK
        return FrameObservation(
            frame=frame_index,
            track=np.arange(len(self.walkers.heights), dtype=np.int64),
            **{key: block[key][i].copy() for key in OBSERVED},
        )

    def _everyone(self) -> Walking:
        """The labelled people, then the outside ones (what the cameras see)."""
        if self.outsiders is None:
            return self.walkers
        return Together([self.walkers, self.outsiders])

    def render(self, frame_index: int, camera_index: int) -> np.ndarray:
        """The image camera ``camera_index`` takes at ``frame_index``: uint8 BGR [H, W, 3]."""
        from models.simulate.render import Renderer, appearance

        if not 0 <= camera_index < self.num_cameras:
            raise MomlocError(f"camera {camera_index} not in 0..{self.num_cameras - 1}")
        with self._lock:
            if self._renderer is None:
                count = len(self._everyone().heights)
                looks = appearance(np.random.default_rng([self.seed, 2]), count)
                self._renderer = Renderer(
                    self.config.room, self.config.wall_height, looks, self.config.outdoor,
                    self.config.furniture,
                )  # fmt: skip
            camera = self.cameras_at(frame_index)[camera_index]
            if self._posed is None or self._posed[0] != frame_index:
                self._posed = (frame_index, self.body_points(frame_index))
            points = self._posed[1]
            background = self._renderer.background(camera)
        return self._renderer.draw(background, camera, points, self._everyone().heights)

    def body_points(self, frame_index: int) -> np.ndarray:
        """World points [P + O, NUM_POINTS, 3] of every body (joints, then auxiliary points):
        the labelled people, then the outside ones."""
        everyone = self._everyone()
        with self._lock:
            states = everyone.states(frame_index, frame_index + 1)
        return body_points(
            states.position, states.heading, states.phase, states.amplitude, everyone.heights,
            *states.postures(),
        )[0]  # fmt: skip

    def observe_block(self, block: int) -> dict[str, np.ndarray]:
        """Frames ``BLOCK * block`` .. ``BLOCK * (block + 1) - 1`` at once, arrays [F, P, ...]."""
        with self._lock:
            if block in self._blocks:
                self._blocks.move_to_end(block)
                return self._blocks[block]
            out = self._compute_block(block)
            self._blocks[block] = out
            while len(self._blocks) > 2:
                self._blocks.popitem(last=False)
            return out

    def _compute_block(self, block: int) -> dict[str, np.ndarray]:
        start = block * BLOCK
        everyone = self._everyone()
        states = everyone.states(start, start + BLOCK)
        points = body_points(
            states.position, states.heading, states.phase, states.amplitude, everyone.heights,
            *states.postures(),
        )  # [F, P, M, 3]  # fmt: skip
        intr, rot, trans, dist = self._camera_arrays(start, start + BLOCK)
        pixels, depth, magnification = project_points(
            points[:, None],
            intr[:, :, None, None],
            rot[:, :, None, None],
            trans[:, :, None, None],
            dist[:, :, None, None],
            with_scale=True,
        )  # [F, K, P, M, 2], [F, K, P, M], [F, K, P, M]
        front = depth > NEAR
        radius = RADII * everyone.heights[:, None]  # [P, M]
        rho = intr[:, :, None, None, 0, 0] * radius * magnification / np.where(front, depth, 1.0)
        # Furniture between a camera and a body point hides it: the box is the visible body's.
        hidden = self.occluders.hidden(points, self.cameras)  # [F, K, P, M]
        volume = front & (radius > 0) & ~hidden
        lo = np.where(volume[..., None], pixels - rho[..., None], np.inf).min(-2)
        hi = np.where(volume[..., None], pixels + rho[..., None], -np.inf).max(-2)
        true_boxes = np.concatenate([lo, hi], -1)
        size = self.image_sizes.astype(float)
        in_image = (hi[..., 0] > 0) & (lo[..., 0] < size[:, 0, None]) & (hi[..., 1] > 0)
        in_image &= lo[..., 1] < size[:, 1, None]
        seen = front[..., MID_HIP] & in_image
        true_boxes = np.where(seen[..., None], true_boxes, np.nan)

        joints_px = np.where(front[..., :17, None], pixels[..., :17, :], np.nan)
        face_away = np.zeros(front[..., :17].shape, dtype=bool)
        head = depth[..., HEAD]
        face_away[..., 0:3] = (depth[..., 0] > head)[..., None]
        face_away[..., 3] = depth[..., 3] > head
        face_away[..., 4] = depth[..., 4] > head
        face_away |= hidden[..., :17]  # a joint behind furniture: occluded like a turned-away one
        weight = np.where(RADII > 0, RADII**2, 0.0)  # a body point's share of the visible body
        hidden_fraction = (hidden * weight).sum(-1) / weight.sum()
        rng = np.random.default_rng([self.seed, 1, block])
        shape = (BLOCK, self.num_cameras, len(everyone.heights))
        boxes, keypoints = detect(
            true_boxes,
            depth[..., MID_HIP],
            joints_px,
            face_away,
            self.image_sizes,
            self.profile,
            rng,
            self._correlated(3, block, (*shape, 5), self.profile.edges.correlation_s),
            self._correlated(6, block, shape, self.profile.miss.correlation_s),
            self._keypoint_draws(block, shape),
            hidden_fraction,
        )
        n = len(self.walkers.heights)  # labelled people first, then the outside ones
        people = {
            "world": states.position,
            "joints": points[:, :, :17],
            "boxes": boxes.transpose(0, 2, 1, 3),
            "keypoints": keypoints.transpose(0, 2, 1, 3, 4),
            "true_boxes": true_boxes.transpose(0, 2, 1, 3),
        }
        out = {key: value[:, :n] for key, value in people.items()}
        for key in ("world", "boxes", "keypoints", "true_boxes"):
            out[f"outside_{key}"] = people[key][:, n:]
        out["false_boxes"] = self._false_boxes(block)
        return out

    def _correlated(
        self, stream: int, block: int, shape: tuple[int, ...], correlation_s: float
    ) -> np.ndarray:
        """Unit normals of ``block`` correlated over ``correlation_s``, continuous across blocks."""
        return correlated_normals(
            np.random.default_rng([self.seed, stream, block + 1]).standard_normal(shape),
            np.random.default_rng([self.seed, stream, block]).standard_normal(shape),
            self.config.fps,
            correlation_s,
        )

    def _keypoint_draws(self, block: int, shape: tuple[int, ...]) -> KeypointDraws | None:
        """Keypoint noise [F, K, P, 17, 2] and pose-miss latents [F, K, P] correlated over the
        profile's ``keypoints.correlation_s``, or None (i.i.d. draws from the block's own
        generator, as before keypoint noise had a correlation time) when it has none."""
        correlation_s = self.profile.keypoints.correlation_s
        if correlation_s <= 0:
            return None
        return KeypointDraws(
            self._correlated(9, block, (*shape, 17, 2), correlation_s),
            self._correlated(10, block, shape, correlation_s),
        )

    def _false_boxes(self, block: int) -> np.ndarray:
        """False positives visible in ``block``: [F, K, Q, 4] (see :mod:`false_positives`)."""
        born = [
            false_positives.births(
                self.profile,
                self.config.fps,
                BLOCK,
                self.image_sizes,
                self._fp_places,
                np.random.default_rng([self.seed, 4, b + 1]),
            )
            for b in (block - 1, block)
        ]
        rng = np.random.default_rng([self.seed, 8, block])
        previous, current = born
        return false_positives.visible(previous, current, self.profile, self.image_sizes, rng)

    def _camera_arrays(self, start: int, stop: int) -> tuple[np.ndarray, ...]:
        """Per frame and camera: K [F,K,3,3], R [F,K,3,3], t [F,K,3], distortion [F,K,2]."""
        per_frame = []
        changes = sorted(
            {start, *(s for ev in self._perturbed.values() for s, _ in ev if start < s < stop)}
        )
        bounds = [*changes, stop]
        for a, b in itertools.pairwise(bounds):
            cams = self.cameras_at(a)
            arrays = (
                np.stack([c.K for c in cams]),
                np.stack([c.R for c in cams]),
                np.stack([c.t for c in cams]),
                np.array([c.distortion for c in cams]),
            )
            per_frame.append([np.broadcast_to(x, (b - a, *x.shape)) for x in arrays])
        return tuple(np.concatenate([seg[i] for seg in per_frame]) for i in range(4))
