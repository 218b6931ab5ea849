"""Speed of ``momloc track`` on a recording and on a dataset's boxes →
bench/results/offline_track.md.

The demo scene (indoor-2cam, seed 7, 3 people, 15 fps) drawn for ``FRAMES`` frames as a
recording (``service.offline.record.record_scene``), then tracked the way ``momloc track`` does
(``service.offline.track``: the shipped detector on every frame set, the demo model, the daemon's
tracker), timed in wall clock and CPU time since the bench box is shared; served accuracy against
the recording's ``truth.npz``. The same frames' simulated boxes (``--detections``) show what the
chain costs without the detector.

Run: ``python -m bench.serving.offline_track`` (about two minutes on 2 cores).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bench.report import RESULTS, machine_line, markdown_table
from capture.recording import Recording
from models.data.dataset import MomDataset
from models.mom.runtime import MomRuntime
from models.simulate import simulate
from service.offline import track as offline
from service.offline.record import TRUTH_FILE, record_scene
from service.offline.track_output import TruthScore
from service.settings import DEMO_MODEL_DIR

FRAMES = 300


def timed_track(feed: offline.Feed, settings, out: Path, truth: MomDataset) -> dict:
    runtime = MomRuntime.load(DEMO_MODEL_DIR)
    pipeline = offline.offline_pipeline(settings, runtime, feed, DEMO_MODEL_DIR)
    score = TruthScore(truth, feed.num_cameras, feed.total)
    cpu = time.process_time()
    summary = offline.run_track(pipeline, feed, out, score=score, progress=False)
    return {
        "sets": summary.frame_sets,
        "wall": summary.seconds,
        "cpu": time.process_time() - cpu,
        "metrics": score.result(),
    }


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        result = simulate("indoor-2cam", FRAMES, seed=7, people=3)
        data = result.dataset.save(folder / "scene.npz")
        record_scene(result.scene, FRAMES, folder / "rec", progress=False)
        truth = MomDataset.load(folder / "rec" / TRUTH_FILE)
        videos = [str(folder / "rec" / f"cam{k}.avi") for k in range(2)]
        settings = offline.offline_settings(None, videos)
        recording = Recording.open(folder / "rec")
        runs = {
            "recording, shipped detector (nanodet) every frame set": timed_track(
                offline.recording_feed(recording, settings), settings, folder / "a", truth
            ),
            "--detections (simulated boxes, no detector)": timed_track(
                offline.detections_feed(data, fps=15.0), settings, folder / "b", truth
            ),
        }
    rows = []
    for name, r in runs.items():
        m = r["metrics"]
        rows.append(
            [
                name,
                r["sets"],
                f"{r['sets'] / r['wall']:.1f}",
                f"{1e3 * r['cpu'] / r['sets']:.0f} ms",
                f"{m['recall']:.1f} %",
                f"{m['precision']:.1f} %",
                f"{m['mota']:.1f} %",
                f"{m['mean']:.3f} m",
            ]
        )
    header = ["input", "frame sets", "sets/s (wall)", "CPU per set", "recall", "precision",
              "MOTA", "mean error"]  # fmt: skip
    text = (
        "# momloc track: offline speed\n\n"
        f"{machine_line()}\n\n"
        f"indoor-2cam, seed 7, 3 people, {FRAMES} frames at 15 fps (two 640×480 cameras), "
        "demo model, the daemon's tracker settings; accuracy at the 0.5 m gate against everyone "
        "in view (the recording's truth.npz).\n\n" + markdown_table(header, rows) + "\n"
    )
    path = RESULTS / "offline_track.md"
    path.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
