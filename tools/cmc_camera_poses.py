"""Print the ``cmc-room`` preset's cameras, derived once from the CMC projection matrices.

Why a tool and not a loader: the CMC data (Ong et al., IEEE TPAMI 2020) is evaluation data that
must never enter the repository or be read at run time, but a preset that hangs its simulated
cameras where the real ones hang needs a handful of pose numbers. This tool decomposes each real
3x4 matrix (RQ) into K, R and the camera centre, and prints what
:class:`models.simulate.CameraSpec` takes: the centre, a look-at target (where the ray through
the image centre meets the floor: a look-at camera has its principal point there), the
horizontal field of view from f_x and, for the record, the real roll (a look-at has none) and
principal point. Run it with the data at hand and paste the numbers into
``models/simulate/presets.py``::

    python tools/cmc_camera_poses.py --data ../shared/data
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.linalg import rq

WIDTH, HEIGHT = 1920, 1024


def camera_pose(matrix: np.ndarray) -> dict[str, object]:
    """Centre, floor target of the image-centre ray, hfov and roll (degrees) of a 3x4 matrix."""
    intrinsics, rotation = rq(matrix[:, :3])
    signs = np.diag(np.sign(np.diag(intrinsics)))
    intrinsics, rotation = intrinsics @ signs, signs @ rotation
    intrinsics = intrinsics / intrinsics[2, 2]
    centre = -np.linalg.solve(matrix[:, :3], matrix[:, 3])
    ray = rotation.T @ np.linalg.solve(intrinsics, [WIDTH / 2, HEIGHT / 2, 1.0])
    if np.linalg.det(rotation) < 0:
        ray = -ray
    target = centre - centre[2] / ray[2] * ray
    return {
        "position": centre.round(3).tolist(),
        "target": target.round(3).tolist(),
        "hfov_deg": round(float(np.degrees(2 * np.arctan(WIDTH / 2 / intrinsics[0, 0]))), 2),
        "roll_deg": round(float(np.degrees(np.arcsin(rotation[0, 2]))), 2),
        "principal_point": intrinsics[:2, 2].round(1).tolist(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    args = parser.parse_args()
    path = args.data / "cmc" / "calibration" / "P_matrices.json"
    if not path.is_file():
        print(f"cmc camera poses: skipped ({path} not found)")
        return
    matrices = json.loads(path.read_text())
    for name in ("cam1", "cam2", "cam3", "cam4"):
        print(name, json.dumps(camera_pose(np.asarray(matrices[name], float))))


if __name__ == "__main__":
    main()
