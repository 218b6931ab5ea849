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
lounge          5 × 4      2        640×480    2       living-room + sofa, coffee table
office-desks    8 × 6      3        640×480    3       office-3cam + two desks with chairs
demo-lounge     10 × 10    2        640×480    3 (+1)  indoor-2cam + a sofa in the demo zone
demo-fall       10 × 10    2        640×480    0 (+1)  indoor-2cam + someone who falls
==============  =========  =======  =========  ======  ===================================

The furnished presets (:mod:`models.simulate.furniture`, :mod:`models.simulate.postures`) have
people who follow a script: in ``lounge`` one sits on the sofa behind the coffee table (which
hides their shins from both cameras) while another walks, stands at the window, crouches to pick
something up and sits in the armchair; in ``office-desks`` two work seated at desks (a desk hides
the legs from the cameras in front of it) while a third walks between them; ``demo-lounge`` is
the demo's room (the demo model's cameras) with a sofa in its ``lounge`` zone and one more
person sitting on it; in ``demo-fall`` one person in the demo's room walks, stands, falls (a
0.8 s drop), lies 20 s and gets up, at three places in turn (:func:`fall_route`). The scripts
loop for an hour.

``cmc-room`` copies the real CMC room at 4 fps: its people are labelled in the authors'
tracking area (x 2.03-6.30 m, the whole depth) and four more walk outside it where the real
room's outside people stand, between the area and the cameras of its x = 0 wall
(``outside_people``, ``outside_region``, see :mod:`models.simulate.outside`; the count fits the
real boxes of outside people per frame, ``bench/real/sim_vs_real.py``), seated
(``outside_posture``: their real boxes are a seated person's height); the people in the area
keep apart as the real ones do (``separation``, ``repulsion``). Its camera poses were
derived once from the data set's projection matrices by ``tools/cmc_camera_poses.py`` (centre, floor
target of the image-centre ray, field of view from f_x; the real rolls of 0.5-2.7° and principal
points 13-52 px off centre are left out): a handful of pose numbers, not the evaluation data.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from common.errors import MomlocError
from models.simulate.furniture import chair, sofa, table
from models.simulate.profile import DetectorProfile, load_profile
from models.simulate.scene import CameraSpec, Perturbation, Scene, SceneConfig
from models.simulate.script import Segment

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


HOUR_S = 3600.0
FACING = {"+x": 0.0, "+y": math.pi / 2, "-x": math.pi, "-y": -math.pi / 2}


def seated(seat: tuple[float, float], facing: str, seconds: float = HOUR_S) -> tuple[Segment, ...]:
    """Someone sitting at ``seat`` (their mid-hip, metres) facing ``facing`` for ``seconds``."""
    return (Segment(seat, seat, seconds, "sitting", FACING[facing]),)


def looping(route: list[Segment], seconds: float = HOUR_S) -> tuple[Segment, ...]:
    """``route`` repeated for at least ``seconds`` (it should end where it starts)."""
    once = sum(s.seconds for s in route)
    return tuple(route * max(1, math.ceil(seconds / once)))


def _walk(a: tuple[float, float], b: tuple[float, float], speed: float = 1.0) -> Segment:
    return Segment(a, b, max(math.dist(a, b) / speed, 0.1))


def fall_route(spots: list[tuple[tuple[float, float], float]], lie_s: float = 20.0,
               stand_s: float = 3.0, drop_s: float = 0.8) -> list[Segment]:  # fmt: skip
    """Walk to each (spot, heading) in turn, stand ``stand_s``, fall there (the body morphs
    into lying over ``drop_s``), lie ``lie_s`` and get up; back to the first spot at the end."""
    route: list[Segment] = []
    points = [spot for spot, _ in spots]
    for i, (spot, heading) in enumerate(spots):
        route.append(Segment(spot, spot, stand_s))
        route.append(Segment(spot, spot, lie_s, "lying", heading, ramp_s=drop_s))
        route.append(_walk(spot, points[(i + 1) % len(points)]))
    return route


_LIVING = room_config("lounge", 5.0, 4.0, 2, people=1, hfov_deg=75.0, distortion=(-0.08, 0.01),
                      heights=(2.0, 1.9))  # fmt: skip
_LOUNGE_ROUTE = [
    _walk((1.0, 1.0), (4.2, 1.2)),
    Segment((4.2, 1.2), (4.2, 1.2), 20.0),  # at the window
    _walk((4.2, 1.2), (3.0, 1.6)),
    Segment((3.0, 1.6), (3.0, 1.6), 4.0, "crouching", FACING["-y"], ramp_s=1.0),
    _walk((3.0, 1.6), (0.8, 2.0)),
    Segment((0.8, 2.0), (0.8, 2.0), 60.0, "sitting", FACING["+x"]),  # the armchair
    _walk((0.8, 2.0), (1.0, 1.0)),
]
_OFFICE = room_config("office-desks", 8.0, 6.0, 3, people=1, hfov_deg=70.0)
_OFFICE_ROUTE = [
    _walk((1.0, 1.0), (6.8, 1.0)),
    _walk((6.8, 1.0), (6.8, 4.8)),
    Segment((6.8, 4.8), (6.8, 4.8), 30.0),  # at the printer
    _walk((6.8, 4.8), (1.2, 4.8)),
    _walk((1.2, 4.8), (1.0, 1.0)),
]
_DEMO = room_config("demo-lounge", 10.0, 10.0, 2, people=3)
DEMO_FALLS = [((3.0, 3.0), 0.0), ((6.5, 4.0), FACING["+y"]), ((4.0, 7.5), 0.5)]

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
        # The real outside people are boxed like seated ones: 0.73 of a standing person's box
        # at their foot point, and they hide few in-area people (models.simulate.outside,
        # bench/results/sim_vs_real_occlusion.md).
        outside_posture="sitting",
        # The real walkers' nearest-neighbour distances (CMC2; models.simulate.people).
        separation=1.0,
        repulsion=0.06,
    ),
    "lounge": dataclasses.replace(
        _LIVING,
        people=0,
        furniture=(
            *sofa(1.4, 3.95, 3.6, "-y"),
            *table(1.7, 2.25, 3.3, 2.75),
            *chair(0.7, 2.0, "+x"),
        ),
        scripts=(seated((2.5, 3.5), "-y"), looping(_LOUNGE_ROUTE)),
    ),
    "office-desks": dataclasses.replace(
        _OFFICE,
        people=0,
        furniture=(
            *table(2.0, 2.6, 3.4, 3.3, top=0.74),
            *chair(2.7, 3.75, "-y"),
            *table(4.6, 2.7, 6.0, 3.4, top=0.74),
            *chair(5.3, 2.25, "+y"),
        ),
        scripts=(seated((2.7, 3.7), "-y"), seated((5.3, 2.3), "+y"), looping(_OFFICE_ROUTE)),
    ),
    "demo-lounge": dataclasses.replace(
        _DEMO,
        furniture=(*sofa(6.0, 7.3, 8.0, "-y"), *table(6.3, 5.6, 7.7, 6.0)),
        scripts=(seated((7.0, 6.85), "-y"),),
    ),
    "demo-fall": dataclasses.replace(
        _DEMO, name="demo-fall", people=0, scripts=(looping(fall_route(DEMO_FALLS)),)
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
