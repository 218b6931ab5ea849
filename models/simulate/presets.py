"""Named scenes and a helper that hangs 1-9 cameras around any room.

``ring_cameras`` puts cameras on the walls, corners first (two adjacent corners for K = 2, like
the paper's Indoor Walking setup), then wall centres, each 5 cm inside the wall at 1.8-2.6 m,
looking at the room centre at waist height: the way people mount webcams on shelves and walls.

==============  =========  =======  =========  ======  ===================================
preset          room (m)   cameras  image      people  like
==============  =========  =======  =========  ======  ===================================
indoor-2cam     10 × 10    2        640×480    3       paper, Indoor Walking (adjacent corners)
indoor-4cam     10 × 10    4        640×480    3       four corners
outdoor-6cam    16 × 25    6        1920×1080  8       MultiviewX (corners and long walls)
living-room     5 × 4      2        640×480    2       a home: wide-angle webcams, distortion
office-3cam     8 × 6      3        640×480    4       a small office
single-cam      6 × 5      1        640×480    2       one webcam (K = 1 tests)
cmc-room        7.67×3.41  4        1920×1024  3 (+4)  the CMC lab (Ong et al., TPAMI 2020)
==============  =========  =======  =========  ======  ===================================

``cmc-room`` copies the real CMC room at 4 fps: its people are labelled in the authors'
tracking area (x 2.03-6.30 m, the whole depth) and four more walk outside it where the real
room's outside people stand, between the area and the cameras of its x = 0 wall
(``outside_people``, ``outside_region``, see :mod:`models.simulate.outside`; the count fits the
real boxes of outside people per frame, ``bench/real/sim_vs_real.py``). Its camera poses were
derived once from the data set's projection matrices by ``tools/cmc_camera_poses.py`` (centre, floor
target of the image-centre ray, field of view from f_x; the real rolls of 0.5-2.7° and principal
points 13-52 px off centre are left out): a handful of pose numbers, not the evaluation data.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from common.errors import MomlocError
from models.simulate.profile import DetectorProfile, load_profile
from models.simulate.scene import CameraSpec, Perturbation, Scene, SceneConfig

INSET = 0.05
CMC_ROOM = (7.67, 3.41)
_HEIGHTS = (2.3, 2.4, 2.2, 2.5, 2.35, 2.25, 2.45, 2.15, 2.55)


def ring_cameras(
    width: float,
    depth: float,
    count: int,
    hfov_deg: float = 65.0,
    image_size: tuple[int, int] = (640, 480),
    distortion: tuple[float, float] = (0.0, 0.0),
    heights: tuple[float, ...] = _HEIGHTS,
    target_height: float = 0.9,
) -> tuple[CameraSpec, ...]:
    """``count`` (1-9) cameras on the walls of a width × depth room, looking at its centre."""
    if not 1 <= count <= 9:
        raise MomlocError(f"cameras: {count} is not between 1 and 9")
    w, d, e = width, depth, INSET
    spots = [
        (e, e), (w - e, e), (w - e, d - e), (e, d - e),  # corners, adjacent first
        (w / 2, e), (w - e, d / 2), (w / 2, d - e), (e, d / 2),  # wall centres
        (w / 4, e),
    ]  # fmt: skip
    target = (w / 2, d / 2, target_height)
    return tuple(
        CameraSpec((x, y, heights[i % len(heights)]), target, hfov_deg, image_size, distortion)
        for i, (x, y) in enumerate(spots[:count])
    )


def room_config(
    name: str,
    width: float,
    depth: float,
    cameras: int,
    people: int = 3,
    *,
    hfov_deg: float = 65.0,
    image_size: tuple[int, int] = (640, 480),
    distortion: tuple[float, float] = (0.0, 0.0),
    heights: tuple[float, ...] = _HEIGHTS,
) -> SceneConfig:
    """A scene of any size with 1-9 ring cameras (see :func:`ring_cameras` for the options)."""
    ring = ring_cameras(width, depth, cameras, hfov_deg, image_size, distortion, heights)
    return SceneConfig(name, (width, depth), ring, people=people)


PRESETS: dict[str, SceneConfig] = {
    "indoor-2cam": room_config("indoor-2cam", 10.0, 10.0, 2, people=3),
    "indoor-4cam": room_config("indoor-4cam", 10.0, 10.0, 4, people=3),
    "outdoor-6cam": SceneConfig(
        "outdoor-6cam",
        (16.0, 25.0),
        tuple(  # four corners and the middle of both long sides
            CameraSpec((x, y, 2.6 if i % 2 == 0 else 2.5), (8.0, 12.5, 0.5), 70.0, (1920, 1080))
            for i, (x, y) in enumerate(
                [
                    (0.05, 0.05),
                    (15.95, 0.05),
                    (15.95, 24.95),
                    (0.05, 24.95),
                    (0.05, 12.5),
                    (15.95, 12.5),
                ]
            )
        ),
        people=8,
        outdoor=True,
    ),
    "living-room": room_config(
        "living-room",
        5.0,
        4.0,
        2,
        people=2,
        hfov_deg=75.0,
        distortion=(-0.08, 0.01),
        heights=(2.0, 1.9),
    ),
    "office-3cam": room_config("office-3cam", 8.0, 6.0, 3, people=4, hfov_deg=70.0),
    "single-cam": room_config("single-cam", 6.0, 5.0, 1, people=2, hfov_deg=70.0),
    "cmc-room": SceneConfig(
        "cmc-room",
        CMC_ROOM,
        tuple(
            CameraSpec(position, target, hfov, (1920, 1024))
            for position, target, hfov in (
                ((0.214, 3.014, 2.185), (4.863, 1.627, 0.0), 82.47),
                ((7.165, 3.378, 2.144), (3.783, 0.298, 0.0), 84.85),
                ((7.592, 0.397, 2.192), (3.298, 1.763, 0.0), 82.94),
                ((0.258, 1.266, 2.136), (4.244, 2.028, 0.0), 84.02),
            )
        ),
        people=3,
        fps=4.0,
        wall_height=2.7,
        area=(2.03, 6.3, 0.0, CMC_ROOM[1]),
        # Where the real boxes of people outside the area stand: their calibrated foot points
        # lie at x 0.60-1.95 m, y 0.40-2.99 m (5th-95th percentiles,
        # bench/results/cmc_detector_measurements.json); walkers keep 0.35 m from the edges.
        outside_people=4,
        outside_region=(0.25, 2.03, 0.05, 3.36),
    ),
}


def get_config(
    preset: str | SceneConfig,
    people: int | None = None,
    fps: float | None = None,
    perturbations: Sequence[Perturbation] | None = None,
    room: tuple[float, float] | None = None,
    cameras: int | None = None,
    detector_profile: str | DetectorProfile | None = None,
    outside_people: int | None = None,
) -> SceneConfig:
    """A preset by name (or a config), with people, fps, perturbations, the room, the detector
    profile (name, JSON path or :class:`DetectorProfile`) or the number of people walking
    outside the set-up area (``SceneConfig.outside_people``) overridden.

    ``room`` (width, depth) and/or ``cameras`` (1-9) re-hang the cameras with
    :func:`ring_cameras`, keeping the preset's field of view, image size and distortion.
    """
    if isinstance(preset, SceneConfig):
        config = preset
    elif preset in PRESETS:
        config = PRESETS[preset]
    else:
        raise MomlocError(
            f"unknown scene preset '{preset}' (available: {', '.join(sorted(PRESETS))})"
        )
    if room is not None or cameras is not None:
        width, depth = room if room is not None else config.room
        if min(width, depth) <= 1.0:
            raise MomlocError(f"room {width} x {depth} m: each side must be over 1 m")
        first = config.cameras[0]
        ring = ring_cameras(
            width, depth, cameras if cameras is not None else len(config.cameras),
            first.hfov_deg, first.image_size, first.distortion,
        )  # fmt: skip
        config = dataclasses.replace(
            config, room=(float(width), float(depth)), cameras=ring, name=f"{config.name}-custom"
        )
    if people is not None:
        config = dataclasses.replace(config, people=int(people))
    if outside_people is not None:
        config = dataclasses.replace(config, outside_people=int(outside_people))
    if fps is not None:
        config = dataclasses.replace(config, fps=float(fps))
    if perturbations is not None:
        config = dataclasses.replace(config, perturbations=tuple(perturbations))
    if detector_profile is not None:  # loaded now: fail early, name the key
        config = dataclasses.replace(config, detector_profile=load_profile(detector_profile))
    return config


def make_scene(
    preset: str,
    *,
    seed: int,
    people: int | None = None,
    fps: float | None = None,
    perturbations: Sequence[Perturbation] | None = None,
    detector_profile: str | None = None,
    outside_people: int | None = None,
) -> Scene:
    """The scene of a preset with the people count and frame rate overridden, optionally
    cameras bumped mid-run and the simulated detector's profile chosen (name or JSON path;
    default the shipped detector's): what synthetic cameras show (``capture.synthetic``)."""
    config = get_config(
        preset,
        people=people,
        fps=fps,
        perturbations=perturbations,
        detector_profile=detector_profile,
        outside_people=outside_people,
    )
    return Scene(config, seed=seed)
