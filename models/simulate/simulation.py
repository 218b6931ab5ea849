"""``simulate``: a whole synthetic recording as a MoM dataset v1 plus the true camera matrices.

Rows are one per (frame, person) seen by at least one camera, ordered by frame then person, so
``frame`` is monotonic per ``track``. Instances that no camera detects are left out: they carry no
observation, and a real recording could not contain them either (``Scene.observe`` still has
them, with all-NaN boxes, for anyone who needs the full ground truth).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.simulate.presets import get_config
from models.simulate.profile import DetectorProfile
from models.simulate.scene import BLOCK, Perturbation, Scene, SceneConfig


@dataclass(frozen=True)
class SimulationResult:
    """The dataset, the true (unperturbed) projection matrices [K,3,4] and the scene itself."""

    dataset: MomDataset
    projections: np.ndarray
    scene: Scene


def simulate(
    preset_or_config: str | SceneConfig,
    frames: int,
    seed: int = 0,
    people: int | None = None,
    perturbation: Perturbation | Sequence[Perturbation] | None = None,
    fps: float | None = None,
    room: tuple[float, float] | None = None,
    cameras: int | None = None,
    detector_profile: str | DetectorProfile | None = None,
    outside_people: int | None = None,
) -> SimulationResult:
    """Observe ``frames`` frames of a preset (by name) or a :class:`SceneConfig`.

    ``people``, ``fps``, ``perturbation``, ``room``, ``cameras`` and ``detector_profile`` (how
    blind the simulated detector is: a shipped profile's name such as ``"ideal"``, ``"ssdlite"``,
    ``"nanodet"`` (the default), or a JSON path) override the preset (see
    :func:`~models.simulate.presets.get_config`), as does ``outside_people``. False positives
    and people outside the set-up area are not rows: they have no label
    (``Scene.observe(i).false_boxes`` and ``.outside_*`` have them).

    Example::

        result = simulate("indoor-2cam", frames=2000, seed=1)
        result.dataset.save("room.npz")
    """
    if frames < 1:
        raise MomlocError(f"frames must be at least 1, got {frames}")
    if isinstance(perturbation, Perturbation):
        perturbation = (perturbation,)
    config = get_config(
        preset_or_config,
        people=people,
        fps=fps,
        perturbations=None if perturbation is None else tuple(perturbation),
        room=room,
        cameras=cameras,
        detector_profile=detector_profile,
        outside_people=outside_people,
    )
    scene = Scene(config, seed)
    parts: dict[str, list[np.ndarray]] = {
        "world": [],
        "boxes": [],
        "keypoints": [],
        "frame": [],
        "track": [],
    }
    for block in range((frames + BLOCK - 1) // BLOCK):
        obs = scene.observe_block(block)
        count = min(BLOCK, frames - block * BLOCK)
        boxes = obs["boxes"][:count]  # [F, P, K, 4]
        keep = np.isfinite(boxes).all(-1).any(-1)  # [F, P]
        f_idx, p_idx = np.nonzero(keep)
        parts["world"].append(obs["world"][:count][keep])
        parts["boxes"].append(boxes[keep])
        parts["keypoints"].append(obs["keypoints"][:count][keep])
        parts["frame"].append(f_idx + block * BLOCK)
        parts["track"].append(p_idx)
    arrays = {key: np.concatenate(value) for key, value in parts.items()}
    if len(arrays["world"]) == 0:
        raise MomlocError(f"scene '{config.name}': no camera saw anybody in {frames} frames")
    dataset = MomDataset(
        world=arrays["world"].astype(np.float32),
        boxes=arrays["boxes"].astype(np.float32),
        frame=arrays["frame"].astype(np.int64),
        track=arrays["track"].astype(np.int64),
        image_size=scene.image_sizes,
        keypoints=arrays["keypoints"].astype(np.float32),
    )
    return SimulationResult(dataset, scene.projection_matrices(), scene)
