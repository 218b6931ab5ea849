"""Synthetic multi-camera scene: cameras, walking people, detector-like boxes, rendered frames.

See ARCHITECTURE.md ("Synthetic scene simulator") and CONTRIBUTING.md (``models.simulate``)::

    from models.simulate import simulate
    result = simulate("indoor-2cam", frames=2000, seed=0)
    result.dataset.save("room.npz"); result.projections  # [K, 3, 4] for the calibrated baseline
    simulate("indoor-2cam", frames=2000, detector_profile="ideal")  # the former kind noise
"""

from models.simulate.camera import PinholeCamera
from models.simulate.presets import PRESETS, get_config, make_scene, ring_cameras, room_config
from models.simulate.profile import (
    DEFAULT_PROFILE,
    DetectorProfile,
    available_profiles,
    load_profile,
)
from models.simulate.scene import CameraSpec, FrameObservation, Perturbation, Scene, SceneConfig
from models.simulate.simulation import SimulationResult, simulate

__all__ = [
    "DEFAULT_PROFILE",
    "PRESETS",
    "CameraSpec",
    "DetectorProfile",
    "FrameObservation",
    "Perturbation",
    "PinholeCamera",
    "Scene",
    "SceneConfig",
    "SimulationResult",
    "available_profiles",
    "get_config",
    "load_profile",
    "make_scene",
    "ring_cameras",
    "room_config",
    "simulate",
]
