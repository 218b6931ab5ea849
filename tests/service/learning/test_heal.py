"""Self-healing: a bumped camera's floor map re-learned from positions the other camera gives."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from models.geometry.floor_prior import FloorPrior
from models.mom.image_transform import apply, boxes_to_model
from models.simulate import Perturbation
from models.simulate.presets import make_scene
from service.learning.heal import HealSamples, _refit_repair, repair
from service.learning.healer import Healer, Session
from service.learning.listener import SelfLabeler
from service.settings import DEMO_MODEL_DIR
from tests.service.learning.frames import FakeModel

BUMP = Perturbation(camera=1, start_frame=0, dx=10.0, roll_deg=3.0)


def camera_views(seed: int, frames: range, bumped: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """True floor positions [N, 2] and camera 1's boxes [N, 4] (ideal boxes), after the bump
    unless ``bumped`` is False."""
    scene = make_scene(
        "indoor-2cam", seed=seed, perturbations=[BUMP] if bumped else [], detector_profile="ideal"
    )
    world, boxes = [], []
    for i in frames:
        obs = scene.observe(i)
        seen = np.isfinite(obs.boxes[:, 1]).all(axis=1)
        world.append(obs.world[seen, :2])
        boxes.append(obs.boxes[seen, 1])
    return np.concatenate(world), np.concatenate(boxes)


def lone_error(prior: FloorPrior, world: np.ndarray, boxes: np.ndarray) -> float:
    lone = np.full((len(world), prior.num_cameras, 4), np.nan)
    lone[:, 1] = boxes
    xy, _ = prior.predict(lone)
    return float(np.nanmedian(np.linalg.norm(xy - world, axis=1)))


def test_a_repair_brings_the_bumped_camera_back_and_passes_its_check() -> None:
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    before = FloorPrior.from_json(meta["floor_prior"]["prior"])
    rng = np.random.default_rng(0)
    world, boxes = camera_views(3, range(0, 1500, 5))
    reference = world + rng.normal(0, 0.1, world.shape)  # the other camera's positions
    samples = HealSamples(
        t=list(np.arange(len(world), dtype=float)),
        world=list(reference),
        std=[0.1] * len(world),
        box=list(boxes),
    )
    fixed = repair(meta, 1, samples, single_m=0.15)
    test_world, test_boxes = camera_views(4, range(0, 600, 7))
    after = FloorPrior.from_json(fixed.meta["floor_prior"]["prior"])
    bumped = lone_error(before, test_world, test_boxes)
    repaired = lone_error(after, test_world, test_boxes)
    unbumped = lone_error(before, *camera_views(4, range(0, 600, 7), bumped=False))
    # back to what the camera did before the bump (the same people, seen from where it was)
    assert repaired < 0.8 * bumped and repaired < 1.1 * unbumped, (bumped, repaired, unbumped)
    assert fixed.passed and fixed.positions == len(world)
    assert fixed.meta["floor_prior"]["policy"] == "prior"
    assert (
        fixed.meta["floor_prior"]["prior"]["cameras"][0]
        == meta["floor_prior"]["prior"]["cameras"][0]
    )
    assert fixed.meta["decoder"]["matrices"][0] == meta["decoder"]["matrices"][0]
    assert fixed.meta["decoder"]["matrices"][1] != meta["decoder"]["matrices"][1]
    assert meta["floor_prior"]["policy"] == "blend"  # the model in service is left as it was


def test_positions_that_do_not_match_the_boxes_fail_the_check() -> None:
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    world, boxes = camera_views(3, range(0, 1500, 5))
    shuffled = np.random.default_rng(1).permutation(world)  # positions of someone else
    samples = HealSamples(
        list(np.arange(len(world), dtype=float)), list(shuffled), [0.1] * len(world), list(boxes)
    )
    try:
        fixed = repair(meta, 1, samples, single_m=0.15)
    except Exception:  # no map fits at all: as good as failing the check
        return
    assert not fixed.passed, fixed.error_m


class StoredModel(FakeModel):
    """The serving model as the healer reads it: its ``model.json`` and directory."""

    def __init__(self, meta: dict) -> None:
        super().__init__(meta=meta)
        self.model_dir = DEMO_MODEL_DIR


class Serving:
    def __init__(self, meta: dict) -> None:
        self.runtime = StoredModel(meta)
        self.reloaded: list[Path] = []

    def reload_model(self, model_dir: str | Path | None = None) -> dict[str, Any]:
        self.reloaded.append(Path(str(model_dir)))
        return {}


def session_with(world: np.ndarray, boxes: np.ndarray) -> Session:
    session = Session(camera=1, since=1e9, wall=0.0, need=len(world))
    session.samples = HealSamples(
        list(np.arange(len(world), dtype=float)), list(world), [0.1] * len(world), list(boxes)
    )
    return session


def test_a_passing_repair_is_served_as_a_copy_of_the_model_and_said_so(tmp_path: Path) -> None:
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    serving = Serving(meta)
    healer = Healer(tmp_path, SelfLabeler(tmp_path, threaded=False), serving)
    world, boxes = camera_views(3, range(0, 1500, 5))
    session = session_with(world, boxes)
    healer._repair(session)
    final = tmp_path / "model"
    assert session.state == "repaired" and serving.reloaded == [final]
    served = json.loads((final / "model.json").read_text())
    assert served["floor_prior"]["policy"] == "prior"
    assert (final / "encoder.onnx").read_bytes() == (DEMO_MODEL_DIR / "encoder.onnx").read_bytes()
    message = healer.status()[0]["message"]
    assert f"re-learned from {len(world)} positions" in message and "camera 1 moved at" in message


def test_a_failing_repair_is_not_served_and_collection_goes_on(tmp_path: Path) -> None:
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    serving = Serving(meta)
    healer = Healer(tmp_path, SelfLabeler(tmp_path, threaded=False), serving)
    world, boxes = camera_views(3, range(0, 1500, 5))
    world, boxes = world[:300], boxes[:300]
    session = session_with(np.random.default_rng(1).permutation(world), boxes)
    healer._repair(session)
    assert serving.reloaded == [] and not (tmp_path / "model").exists()
    assert session.state == "collecting" and session.need == 600
    assert session.samples.n == 0 and "collecting more positions" in (session.message or "")


def test_references_long_along_a_line_of_sight_are_refined_with_their_covariance() -> None:
    """Two cameras: the references are the other camera's single views, 0.5 m std along its
    line of sight and 5 cm across; their covariances let the moved camera's own boxes place
    them along it (service.learning.heal, errors-in-variables). The refit alone: the fallback
    when no image transform explains the positions."""
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    camera0 = np.asarray(make_scene("indoor-2cam", seed=3).cameras[0].position)[:2]
    world, boxes = camera_views(3, range(0, 1500, 5))
    sight = (world - camera0) / np.linalg.norm(world - camera0, axis=1, keepdims=True)
    across = np.c_[-sight[:, 1], sight[:, 0]]
    rng = np.random.default_rng(0)
    along_m, across_m = rng.normal(0, 0.5, len(world)), rng.normal(0, 0.05, len(world))
    reference = world + along_m[:, None] * sight + across_m[:, None] * across
    cov = 0.25 * sight[:, :, None] * sight[:, None] + 0.0025 * across[:, :, None] * across[:, None]
    test_world, test_boxes = camera_views(4, range(0, 600, 7))
    errors = {}
    for name, covariances in (("plain", []), ("refined", list(cov))):
        t = list(np.arange(len(world), dtype=float))
        samples = HealSamples(t, list(reference), [0.5] * len(world), list(boxes), covariances)
        fixed = _refit_repair(meta, 1, samples, reachable=0.5)
        after = FloorPrior.from_json(fixed.meta["floor_prior"]["prior"])
        errors[name] = lone_error(after, test_world, test_boxes)
    unbumped = lone_error(
        FloorPrior.from_json(meta["floor_prior"]["prior"]),
        *camera_views(4, range(0, 600, 7), bumped=False),
    )
    assert errors["refined"] < 0.8 * errors["plain"], errors
    assert errors["refined"] < 1.3 * unbumped, (errors, unbumped)


def line_of_sight_references(
    world: np.ndarray, seed: int, along_m: float = 0.4, across_m: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """Camera 0's single views of ``world``: long along its line of sight; and their
    covariances."""
    camera0 = np.asarray(make_scene("indoor-2cam", seed=3).cameras[0].position)[:2]
    sight = (world - camera0) / np.linalg.norm(world - camera0, axis=1, keepdims=True)
    across = np.c_[-sight[:, 1], sight[:, 0]]
    rng = np.random.default_rng(seed)
    reference = (
        world
        + rng.normal(0, along_m, len(world))[:, None] * sight
        + rng.normal(0, across_m, len(world))[:, None] * across
    )
    cov = along_m**2 * sight[:, :, None] * sight[:, None]
    cov += across_m**2 * across[:, :, None] * across[:, None]
    return reference, cov


def test_a_bump_by_a_known_transform_is_recovered_to_a_pixel() -> None:
    """The bump a known roll and shift of camera 1's image; the references what the former
    maps said before the bump plus 5 cm of noise (several cameras' positions): 80 positions
    give the transform back to under a pixel where people are seen (a homography, with four
    more unknowns, to 3)."""
    from service.learning.bump import fit
    from tests.models.test_image_transform import rolled, seen_through

    world, boxes = camera_views(3, range(0, 1500, 5), bumped=False)
    alone = np.full((len(world), 2, 4), np.nan)
    alone[:, 1] = boxes
    prior = FloorPrior.fit_arrays(world, alone, np.array([[640, 480], [640, 480]]), points="both")
    said, _ = prior.predict(alone)
    truth = rolled(3.0, (10.0, 0.0), (320.0, 240.0))
    pick = np.random.default_rng(2).choice(len(world), 80, replace=False)
    reference = said[pick] + np.random.default_rng(0).normal(0, 0.05, (80, 2))
    cov = np.tile(np.eye(2) * 0.05**2, (80, 1, 1))
    bumped = seen_through(truth, boxes[pick])
    where = (boxes[:, :2] + boxes[:, 2:]) / 2
    for dof, within in ((3, 1.0), (8, 3.0)):
        h = fit(prior, 1, reference, cov, bumped, None, dof)
        off = np.linalg.norm(apply(h, where) - apply(truth, where), axis=1)
        assert np.percentile(off, 95) < within, (dof, np.percentile(off, 95))
    assert np.median(np.linalg.norm(apply(truth, where) - where, axis=1)) > 5  # the bump shows


def test_a_bumped_camera_is_repaired_as_one_image_transform_from_few_positions() -> None:
    """The simulator's bump (roll 3°, shift 10 px) seen in ideal boxes; 80 references from the
    other camera's single views: the repair is the former model with camera 1's boxes mapped
    back, and its lone views are as good as before the bump."""
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    before = FloorPrior.from_json(meta["floor_prior"]["prior"])
    world, boxes = camera_views(3, range(0, 1500, 5))
    pick = np.random.default_rng(2).choice(len(world), 80, replace=False)
    reference, cov = line_of_sight_references(world[pick], seed=6)
    samples = HealSamples(
        list(np.arange(80, dtype=float)), list(reference), [0.4] * 80, list(boxes[pick]), list(cov)
    )
    fixed = repair(meta, 1, samples, single_m=0.15)
    assert fixed.how == "transform" and fixed.passed, fixed
    assert fixed.meta["floor_prior"] == meta["floor_prior"]  # the former maps, unchanged
    assert fixed.meta["decoder"] == meta["decoder"]
    h = np.asarray(fixed.meta["image_transforms"][1])
    assert fixed.meta["image_transforms"][0] is None
    test_world, test_boxes = camera_views(4, range(0, 600, 7))
    bumped = lone_error(before, test_world, test_boxes)
    repaired = lone_error(before, test_world, boxes_to_model(h, test_boxes))
    unbumped = lone_error(before, *camera_views(4, range(0, 600, 7), bumped=False))
    assert repaired < 1.1 * unbumped and repaired < 0.8 * bumped, (bumped, repaired, unbumped)


def test_when_no_image_transform_explains_the_positions_the_maps_are_refitted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A transform that leaves the bump in place (the identity: as if the camera had been
    moved, not turned) fails the held-out check, so the camera's maps are refitted instead."""
    import service.learning.heal

    monkeypatch.setattr(service.learning.heal, "fit_bump", lambda *args, **kwargs: np.eye(3))
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    world, boxes = camera_views(3, range(0, 1500, 5))
    cov = np.tile(np.eye(2) * 0.1**2, (len(world), 1, 1))
    reference = world + np.random.default_rng(0).normal(0, 0.1, world.shape)
    samples = HealSamples(
        list(np.arange(len(world), dtype=float)),
        list(reference),
        [0.1] * len(world),
        list(boxes),
        list(cov),
    )
    fixed = repair(meta, 1, samples, single_m=0.15)
    assert fixed.how == "refit" and fixed.passed, fixed.error_m
    assert "image_transforms" not in fixed.meta
    assert fixed.meta["floor_prior"]["prior"] != meta["floor_prior"]["prior"]


def _pairing_frame(second_at_heights: float) -> tuple[Any, float]:
    """A person at (5, 5) seen by camera 0, camera 1 bumped (their box 20 px off where its
    former map puts them) and a second box in camera 1 that far beside it (box heights); the
    model's floor prior fitted on exact marks (``tests.models.test_floor_prior``)."""
    from tests.models.test_floor_prior import _boxes, _marks
    from tests.service.learning.frames import Person, frame_result

    world, boxes = _marks(sway=0.0)
    model = FakeModel()
    model.floor_prior = FloorPrior.fit_arrays(world, boxes, model.image_sizes)
    box = _boxes(np.array([[5.0, 5.0]]))[0]
    bumped = box[1] + np.array([20.0, 0.0, 20.0, 0.0])
    height = float(bumped[3] - bumped[1])
    second = bumped + np.array([1.0, 0.0, 1.0, 0.0]) * second_at_heights * height
    people = [
        Person(5.0, 5.0, [box[0].tolist(), bumped.tolist()], track=1),
        Person(8.0, 8.0, [None, second.tolist()], track=2),  # seen by the moved camera only
    ]
    return frame_result(people, model=model), float(bumped[0])


@pytest.mark.parametrize("apart, paired", [(0.9, True), (0.1, False)])
def test_the_moved_camera_box_is_paired_when_clearly_the_nearest(
    apart: float, paired: bool
) -> None:
    from service.learning.heal import heal_samples
    from service.learning.labels import LabelRules

    result, left = _pairing_frame(apart)
    samples = HealSamples.empty()
    added = heal_samples(result, 1, LabelRules(), {}, samples)
    assert added == int(paired)
    if paired:  # the person's own box, not the one beside it
        assert samples.box[0][0] == pytest.approx(left)
        np.testing.assert_allclose(samples.world[0], [5.0, 5.0], atol=0.05)
