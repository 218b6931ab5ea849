"""``momloc record`` and ``momloc simulate --record``: write recordings (:mod:`capture.recording`).

Live recording takes frame sets from the same rig the daemon builds (``service.daemon.build_rig``)
and the same way the pipeline does (wait up to 0.1 s for frames newer than the last set, skip a
set whose frames are all the same as before), so a recording holds what the pipeline would have
fused, camera by camera, with the capture times it would have used. Synthetic cameras are drawn
on every frame for a recording (``synthetic.detections: rendered``): the simulator's boxes are no
frames and cannot be recorded.

Cost (measured 2026-12-01, 2 cores, loaded, drawn 640×480 frames): MJPG encoding 3.8 CPU-ms per
image (decoding for replay 3.6 ms), ~30 kB per image, so two cameras at 30 fps take about a
quarter of a core and 1.8 MB/s. Encoding runs in the recording loop, like the pipeline's own
work: if the machine cannot keep up, frame sets are skipped (the camera workers keep only the
newest frame), never queued.

Simulated recordings draw every scene frame of every camera and stamp frame *i* at ``i / fps``
seconds (scene time from 0, not wall clock): deterministic, and frame set *i* is frame *i* of
the dataset written beside it, which ``momloc track --truth`` relies on. The folder also gets
``truth.npz``: everyone in view, the fairer truth for the real detector (see ``_InViewTruth``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from capture.recording import RecordingWriter, check_new_folder
from capture.rig import FrameSet
from capture.worker import Frame
from common.errors import MomlocError
from service.settings import POSITIONS_ONLY, Settings, SyntheticCamera
from service.stop_signals import deferred

if TYPE_CHECKING:  # the simulator is imported where a scene is drawn
    from models.simulate.observation import FrameObservation
    from models.simulate.scene import Scene
    from service.pipeline.live import Rig

NO_FRAMES_S = 10.0  # no camera delivered anything this long: the rig is dead, stop with an error
PROGRESS_EVERY_S = 0.5


@dataclass(frozen=True)
class RecordSummary:
    folder: Path
    frame_sets: int
    seconds: float
    images: list[int]

    def line(self) -> str:
        per_camera = ", ".join(f"cam{k} {n} images" for k, n in enumerate(self.images))
        return f"{self.folder}: {self.frame_sets} frame sets in {self.seconds:.1f} s ({per_camera})"


def _frame_seqs(frame_set: FrameSet | None) -> tuple[int, ...] | None:
    if frame_set is None:
        return None
    seqs = tuple(-1 if f is None else int(f.seq) for f in frame_set.frames)
    return None if all(s < 0 for s in seqs) else seqs


def record_live(
    settings: Settings,
    out: str | Path,
    seconds: float | None,
    *,
    progress: TextIO | None = sys.stderr,
    clock: Callable[[], float] = time.monotonic,
) -> RecordSummary:
    """Record the configured cameras for ``seconds`` (None: until Ctrl-C) into ``out``."""
    from service.pipeline.build import build_rig, camera_name

    if settings.privacy == POSITIONS_ONLY:  # before opening cameras or making the folder
        raise MomlocError(
            "privacy is positions_only (setting privacy, MOMLOC_PRIVACY): recording camera "
            "video is off"
        )
    if any(isinstance(c, SyntheticCamera) for c in settings.cameras):
        drawn = settings.synthetic.model_copy(update={"detections": "rendered"})
        settings = settings.model_copy(update={"synthetic": drawn})
    check_new_folder(out)  # before opening cameras
    names = [camera_name(c) for c in settings.cameras]
    rig, player = build_rig(settings)
    source: dict[str, Any] = {"cameras": [c.model_dump(mode="json") for c in settings.cameras]}
    if player is not None:
        source["synthetic"] = settings.synthetic.model_dump(mode="json")
    writer = RecordingWriter(out, names, fps=_nominal_fps(settings), source=source)
    start: float | None = None  # the first frame set starts the clock (cameras take a while)
    last_frame = clock()
    shown = 0.0
    previous: FrameSet | None = None
    last_seqs: tuple[int, ...] | None = None
    rig.start()
    try:
        while seconds is None or start is None or clock() - start < seconds:
            frame_set = rig.frame_set(after=previous, timeout=0.1)
            seqs = _frame_seqs(frame_set)
            now = clock()
            if frame_set is None or seqs is None or seqs == last_seqs:
                if now - last_frame > NO_FRAMES_S:
                    raise MomlocError(_silence(rig, NO_FRAMES_S))
                time.sleep(0.002)
                continue
            writer.add(frame_set)
            previous, last_seqs, last_frame = frame_set, seqs, now
            start = now if start is None else start
            if progress is not None and now - shown >= PROGRESS_EVERY_S:
                shown = now
                total = " (Ctrl-C stops)" if seconds is None else f" / {seconds:g} s"
                progress.write(
                    f"\rrecording {out}: {now - start:5.1f} s{total}, "
                    f"{writer.frame_sets} frame sets "
                )
                progress.flush()
    except KeyboardInterrupt:
        pass  # Ctrl-C or SIGTERM (service.stop_signals) is the normal end of an open recording
    finally:
        with deferred():  # a signal now waits until the manifest is written
            rig.stop()
            writer.close()
            if progress is not None:
                progress.write("\n")
    elapsed = 0.0 if start is None else clock() - start
    return RecordSummary(Path(out), writer.frame_sets, elapsed, writer.counts)


def _nominal_fps(settings: Settings) -> float:
    if any(isinstance(c, SyntheticCamera) for c in settings.cameras):
        return float(settings.synthetic.fps)
    rates = [c.fps for c in settings.cameras if not isinstance(c, SyntheticCamera)]
    return float(max((r for r in rates if r), default=30.0))


def _silence(rig: Rig, seconds: float) -> str:
    errors = [s.error for s in rig.states() if s.error]
    why = f" ({errors[0]})" if errors else ""
    return f"no camera delivered a frame for {seconds:g} s{why}"


def record_scene(
    scene: Scene, frames: int, out: str | Path, *, progress: bool = True
) -> RecordSummary:
    """Draw scene frames 0..frames-1 of every camera into a recording (see the module docstring)."""
    from tqdm import tqdm

    names = [f"synthetic-{k}" for k in range(scene.num_cameras)]
    source = {"simulator": {"preset": scene.config.name, "seed": scene.seed, "fps": scene.fps}}
    writer = RecordingWriter(out, names, fps=scene.fps, source=source)
    truth = _InViewTruth(scene.image_sizes)
    try:
        for i in tqdm(range(frames), desc="drawing", unit="frame", disable=not progress):
            t = i / scene.fps
            images = [scene.render(i, k) for k in range(scene.num_cameras)]
            frames_now: list[Frame | None] = [Frame(k, im, t, i) for k, im in enumerate(images)]
            writer.add(FrameSet(frames_now, skew=0.0))
            truth.add(scene.observe(i))
    finally:
        writer.close()
    truth.save(Path(out) / TRUTH_FILE)
    return RecordSummary(Path(out), writer.frame_sets, frames / scene.fps, writer.counts)


TRUTH_FILE = "truth.npz"


class _InViewTruth:
    """Everyone in view of a simulated recording, as a dataset v1 file (``truth.npz``).

    Why beside the dataset ``momloc simulate`` writes: that one has rows only for people the
    *simulated* detector reports, so a person the real detector finds in the drawn frames but the
    simulated one misses would count as a ghost (measured on the demo scene, 60 frames, shipped
    detector and demo model: precision 68 % against that file, 78 % against this one; recall
    88-89 % against both). Here a person is in view of camera k when their true body box keeps
    at least half its area inside the image (``service.offline.stream_eval.in_view``, the
    served-accuracy benchmark's rule); ``boxes`` are those true boxes clipped to the image, NaN
    elsewhere.
    """

    def __init__(self, image_sizes: np.ndarray) -> None:
        self.sizes = np.asarray(image_sizes, np.float64)
        self.rows: dict[str, list[np.ndarray]] = {
            "world": [],
            "boxes": [],
            "frame": [],
            "track": [],
        }

    def add(self, obs: FrameObservation) -> None:
        from service.offline.stream_eval import MIN_VISIBLE_FRACTION, in_view

        boxes = np.asarray(obs.true_boxes, np.float64)
        seen = np.stack(
            [
                in_view(boxes[:, [k]], self.sizes[[k]], MIN_VISIBLE_FRACTION)
                for k in range(len(self.sizes))
            ],
            axis=1,
        )  # [P, K]
        keep = seen.any(axis=1)
        clipped = np.concatenate(
            [np.clip(boxes[..., :2], 0, self.sizes), np.clip(boxes[..., 2:], 0, self.sizes)], -1
        )
        clipped[~seen] = np.nan
        self.rows["world"].append(np.asarray(obs.world)[keep, :2])
        self.rows["boxes"].append(clipped[keep])
        self.rows["frame"].append(np.full(int(keep.sum()), obs.frame))
        self.rows["track"].append(np.asarray(obs.track)[keep])

    def save(self, path: Path) -> None:
        from models.data.dataset import MomDataset

        arrays = {key: np.concatenate(parts) for key, parts in self.rows.items()}
        if not len(arrays["world"]):
            return  # nobody in view: no truth to score against
        MomDataset(
            world=arrays["world"].astype(np.float32),
            boxes=arrays["boxes"].astype(np.float32),
            frame=arrays["frame"].astype(np.int64),
            track=arrays["track"].astype(np.int64),
            image_size=self.sizes.astype(np.int32),
        ).save(path)
