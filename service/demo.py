"""The embedded demo: the full daemon on the simulator's scene with the shipped demo model.

Nothing is special-cased: the demo builds ordinary :class:`~service.settings.Settings` with
``synthetic`` cameras and hands them to the same ``build_daemon`` as ``momloc serve``. The only
choice is where the boxes come from (``synthetic.detections``):

- ``simulated`` (default): the simulator's boxes enter the pipeline at the detection stage,
  as blind as the shipped detector (``synthetic.detector_profile``, default ``nanodet``: misses
  by size, occlusion and truncation, edge errors, false positives, all persisting over frames;
  ``--profile ideal`` for the former kind noise). Cheap, so the map runs at the demo's 30 fps
  even on a small machine.
- ``rendered``: frames drawn by the simulator go through the real SSDLite detector. Shows the
  whole chain, but the detector finds the drawn figures only at some sizes (see README), so
  people flicker in and out where it misses them, and it costs ~20 ms of CPU per frame set.
"""

from __future__ import annotations

import os
from typing import Literal

from models.simulate import get_config
from service.settings import DEMO_MODEL_DIR, Settings, load_settings

DEMO_PRESET = "indoor-2cam"
DEMO_SEED = 7
DEMO_PEOPLE = 3
DEMO_FPS = 30.0
# Two zones in the 10 m x 10 m demo room, so the map, /v1/zones and MQTT have something to show:
# a rectangle and a concave L (MOMLOC_ZONES replaces them).
DEMO_ZONES = [
    {"name": "kitchen", "polygon": [[0.5, 0.5], [4.0, 0.5], [4.0, 4.0], [0.5, 4.0]]},
    {
        "name": "lounge",
        "polygon": [[5.0, 5.0], [9.5, 5.0], [9.5, 9.5], [7.5, 9.5], [7.5, 7.0], [5.0, 7.0]],
    },
]


def demo_settings(
    *,
    host: str | None = None,
    port: int | None = None,
    detections: Literal["rendered", "simulated"] | None = None,
    people: int | None = None,
    seed: int | None = None,
    profile: str | None = None,
) -> Settings:
    """Settings for the demo scene; ``MOMLOC_*`` environment variables still apply."""
    config = get_config(DEMO_PRESET)
    synthetic = {
        "preset": DEMO_PRESET,
        "seed": DEMO_SEED if seed is None else seed,
        "people": DEMO_PEOPLE if people is None else people,
        "fps": DEMO_FPS,
    }
    if detections is not None:
        synthetic["detections"] = detections
    if profile is not None:
        synthetic["detector_profile"] = profile
    return load_settings(
        None,
        cameras=[{"type": "synthetic", "index": k} for k in range(len(config.cameras))],
        model_dir=DEMO_MODEL_DIR,
        synthetic=synthetic,
        host=host,
        port=port,
        zones=None if "MOMLOC_ZONES" in os.environ else DEMO_ZONES,
    )
