"""Camera-moved alert through the real pipeline: synthetic rig with a bumped camera, the shipped
demo model, simulated detections; health must name the bumped camera and only that one."""

from __future__ import annotations

import dataclasses

import pytest

from capture.synthetic import SyntheticRig
from capture.worker import Frame
from models.mom.runtime import MomRuntime
from models.simulate import Perturbation, make_scene
from service.api.state import Daemon
from service.demo import DEMO_PEOPLE, DEMO_PRESET, DEMO_SEED
from service.detection.simulated import SimulatedDetections
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.settings import DEMO_MODEL_DIR

FPS = 30.0
STEP = 2  # process every other scene frame (a loaded machine drops frames the same way)
BUMP = 420  # 14 s: after the 10 s reprojection warm-up and the ~5 s image reference
END = 690  # 23 s


def _health_over_time(bump: Perturbation) -> list[tuple[int, dict]]:
    scene = make_scene(
        DEMO_PRESET, seed=DEMO_SEED, people=DEMO_PEOPLE, fps=FPS, perturbations=[bump]
    )
    rig = SyntheticRig(scene, fps=FPS, render_every=6)  # previews at 5 Hz, like the demo
    pipeline = Pipeline(
        rig,
        SimulatedDetections(scene),
        Hub(),
        num_cameras=2,
        runtime=MomRuntime.load(DEMO_MODEL_DIR),
        shift_threaded=False,
    )
    daemon = Daemon(hub=pipeline.hub, pipeline=pipeline, camera_names=["left", "right"])
    out = []
    for index in range(0, END, STEP):
        frame_set = rig.produce(index)
        frames: list[Frame | None] = [
            None if f is None else dataclasses.replace(f, timestamp=1000.0 + index / FPS)
            for f in frame_set.frames
        ]
        pipeline.process(dataclasses.replace(frame_set, frames=frames))
        if index % 30 == 0:
            out.append((index, daemon.health()))
    return out


@pytest.mark.parametrize(
    "bump",
    [
        Perturbation(camera=1, start_frame=BUMP, dx=20.0),  # invisible to the reprojection error
        Perturbation(camera=0, start_frame=BUMP, dy=25.0, roll_deg=1.5),
    ],
    ids=["cam1-horizontal-20px", "cam0-vertical-roll"],
)
def test_health_names_the_bumped_camera(bump: Perturbation) -> None:
    history = _health_over_time(bump)
    other = 1 - bump.camera
    for index, health in history:
        cams = [c["alignment"] for c in health["cameras"]]
        if index < BUMP:
            assert not cams[0]["moved"] and not cams[1]["moved"], (index, cams)
        if index >= BUMP + 6 * FPS:  # 1 s checks + 3 s hold, with margin
            assert cams[bump.camera]["moved"] and cams[bump.camera]["shift_moved"], (index, cams)
            assert not cams[other]["moved"], (index, cams)
            assert health["status"] == "degraded"
    last = history[-1][1]["cameras"]
    alignment = last[bump.camera]["alignment"]
    assert alignment["reference"] == "ready" and alignment["shift_px"] > 15
    name = ["left", "right"][bump.camera]
    assert f"camera {bump.camera} ({name})" in alignment["message"]
    assert "momloc collect" in alignment["message"] and "momloc train" in alignment["message"]
    assert last[other]["alignment"]["message"] is None
    assert last[other]["alignment"]["shift_px"] < 2


def _states(shift_moved, reference, reprojection_moved):
    from service.camera_health.image_shift import CameraShiftState
    from service.camera_health.reprojection import CameraAlignment

    shift = [
        CameraShiftState(k, ref, 20.0 if m else 0.1, 0.6, m, 1.0)
        for k, (m, ref) in enumerate(zip(shift_moved, reference, strict=True))
    ]
    errors = [
        CameraAlignment(k, 20.0 if m else 5.0, 5.0, m, None)
        for k, m in enumerate(reprojection_moved)
    ]
    return errors, shift


def test_combine_attributes_a_shared_error_rise_to_the_camera_whose_image_moved() -> None:
    from service.camera_health.reprojection import combine

    errors, shift = _states([False, True], ["ready", "ready"], [True, True])
    assert [c.moved for c in combine(errors, shift)] == [False, True]
    # no image reference yet: the reprojection error alone decides
    errors, shift = _states([False, False], ["collecting", "collecting"], [True, False])
    verdict = combine(errors, shift, ["door", "window"])
    assert [c.moved for c in verdict] == [True, False]
    assert verdict[0].message is not None
    assert verdict[0].message.startswith("camera 0 (door) looks moved: reprojection error 20.0")
    # the images see nothing but the error stays high: still reported, saying so
    errors, shift = _states([False, False], ["ready", "ready"], [False, True])
    verdict = combine(errors, shift)
    assert [c.moved for c in verdict] == [False, True]
    assert "the image check sees no shift" in (verdict[1].message or "")
