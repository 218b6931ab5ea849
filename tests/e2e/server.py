"""Start the real daemon (uvicorn on a loopback port, in a thread) for end-to-end tests."""

from __future__ import annotations

import itertools
import signal
import subprocess
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from capture.rig import FrameSet
from capture.synthetic import SyntheticRig
from capture.worker import Frame
from models.simulate.scene import Scene
from service.api.server import serve_in_thread
from service.api.state import Daemon
from service.daemon import build_daemon
from service.demo import DEMO_PRESET, demo_settings
from service.outputs.wiring import Outputs
from service.pipeline.hub import Hub
from service.pipeline.live import Rig
from service.setup.session import SetupSession
from service.setup.training import TrainingJob
from service.snapshot import SnapshotBody


@dataclass
class RunningServer:
    daemon: Daemon
    port: int
    token: str | None
    app: Any = None  # the served ASGI app (its routes)

    @property
    def http(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    @property
    def setup(self) -> SetupSession:
        """The daemon's set-up session (``build_daemon`` always makes one)."""
        assert self.daemon.setup is not None
        return self.daemon.setup

    @property
    def outputs(self) -> Outputs:
        """The daemon's outputs (``build_daemon`` always builds them)."""
        assert self.daemon.outputs is not None
        return self.daemon.outputs

    @property
    def training(self) -> TrainingJob:
        """The daemon's training job (``build_daemon`` always makes one)."""
        assert self.daemon.training is not None
        return self.daemon.training

    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"} if self.token else {}

    def get(self, path: str, **kw: Any) -> httpx.Response:
        headers = {**self.headers(), **kw.pop("headers", {})}
        return httpx.get(self.http + path, headers=headers, timeout=10, **kw)

    def wait_for_seq(self, seq: int, timeout: float = 150.0) -> None:
        """A liveness bound, generous: a loaded 2-core machine ran the lock-step pipeline at
        10 frame sets a second (330 took longer than the 30 s this used to allow)."""
        deadline = time.time() + timeout
        while self.daemon.hub.latest().seq < seq:
            if time.time() > deadline:
                raise TimeoutError(f"pipeline did not reach seq {seq}: {self.daemon.health()}")
            time.sleep(0.02)


class LockstepRig(SyntheticRig):
    """The demo's synthetic rig without real-time pacing: scene frame i+1 is drawn only once the
    pipeline has processed frame i, and frames carry scene time (``t0 + i / fps``).

    Why: accuracy checks must not depend on the machine's load. Paced in real time, a busy
    machine makes the pipeline skip frames, so tracking sees fewer, further-apart updates and
    the same code scores worse. In lock-step every run processes the very same frames with the
    very same timestamps, on a fast or a slow machine; the server, stream and clients stay real.
    """

    def __init__(self, rig: Rig, hub: Hub) -> None:
        assert isinstance(rig, SyntheticRig)  # the demo's
        super().__init__(rig.scene, rig.cameras, fps=rig.fps, render_every=rig.render_every)
        self.hub = hub

    def produce(self, index: int) -> FrameSet:
        drawn = self.render_every > 0 and index % self.render_every == 0
        images = [self.render(index, camera) if drawn else None for camera in self.cameras]
        timestamp = self.tick_time(index)  # scene time: the tracker's clock follows the scene
        self.stamp(index, timestamp)
        self._produced = [*self._produced[-59:], time.time()]
        frames: list[Frame | None] = [
            Frame(k, image, timestamp, index) for k, image in enumerate(images)
        ]
        return FrameSet(frames=frames, skew=0.0)

    def _run(self) -> None:
        for index in itertools.count(1):
            if self._stop.is_set():
                return
            before = self.hub.latest().seq
            frame_set = self.produce(index)
            with self._new_frames:
                self._latest = frame_set
                self._new_frames.notify_all()
            while self.hub.latest().seq <= before:  # one frame set, one snapshot
                if self._stop.wait(0.002):
                    return


@contextmanager
def running_server(
    *, port: int = 0, static: dict[str, Path] | None = None, **settings: Any
) -> Iterator[RunningServer]:
    """The demo daemon (synthetic scene, shipped model) on a loopback port (0: a free one).

    ``lockstep=True`` replaces the real-time synthetic rig by :class:`LockstepRig` and runs the
    detector inline on every frame set (``detection.schedule: every_frame``): the scheduled
    detector runs beside the pipeline on wall-clock time, so how many frame sets got fresh
    boxes would depend on the machine's load. ``publishers`` are added to the hub before the
    pipeline starts, so they see every snapshot from seq 1.
    """
    lockstep = settings.pop("lockstep", False)
    token = settings.pop("token", None)
    publishers = settings.pop("publishers", ())
    # The simulator's boxes unless a test asks for the drawn frames through the detector: these
    # tests are about the server, and the detector would only add CPU load and timing slack.
    settings.setdefault("detections", "simulated")
    # The walkers alone (the counts and zones these tests were written for) unless a test asks
    # for the demo as it plays (scene=DEMO_SCENE: a person seated on the sofa too).
    settings.setdefault("scene", DEMO_PRESET)
    model_dir = settings.pop("model_dir", None)
    guard = {k: settings.pop(k) for k in ("allowed_origins", "allowed_hosts") if k in settings}
    # self-labels only where a test asks (with its own data_dir): not into the working folder
    learning = settings.pop("learning", {"enabled": False})
    data_dir = settings.pop("data_dir", None)
    config = demo_settings(host="127.0.0.1", **settings)
    if model_dir:
        config = config.model_copy(update={"model_dir": Path(model_dir)})
    config = config.model_copy(
        update={
            "learning": config.learning.model_copy(update=learning),
            **({} if data_dir is None else {"data_dir": Path(data_dir)}),
        }
    )
    if lockstep:
        inline = config.detection.model_copy(update={"schedule": "every_frame"})
        config = config.model_copy(update={"detection": inline})
    daemon = build_daemon(config)
    daemon.token = token
    if lockstep:
        daemon.pipeline.rig = LockstepRig(daemon.pipeline.rig, daemon.hub)
    for key, value in guard.items():
        setattr(daemon, key, list(value))
    for publisher in publishers:  # before the pipeline starts: they see every snapshot
        daemon.hub.add_publisher(publisher)
    background = serve_in_thread(daemon, port=port, static=static)
    try:
        yield RunningServer(daemon, background.port, token, background.server.config.app)
    finally:
        background.stop()


def match_to_truth(rig: Rig, messages: Sequence[SnapshotBody]) -> tuple[np.ndarray, int, int]:
    """Served people vs the scene's truth (everyone some camera's detector reports), matched one
    to one per message: the matched errors [m], people reported, people visible. ``rig``: the
    demo's synthetic rig, showing a simulated scene."""
    from scipy.optimize import linear_sum_assignment

    assert isinstance(rig, SyntheticRig) and isinstance(rig.scene, Scene)
    errors: list[float] = []
    reported = visible = 0
    for message in messages:
        truth = rig.scene.observe(rig.index_at(message["t"]))
        seen = np.isfinite(truth.boxes).all(axis=2).any(axis=1)
        gt = truth.world[seen, :2]
        got = np.array([[p["x"], p["y"]] for p in message["people"]]).reshape(-1, 2)
        reported += len(got)
        visible += len(gt)
        if len(got) and len(gt):
            cost = np.linalg.norm(got[:, None] - gt[None], axis=2)
            rows, cols = linear_sum_assignment(cost)
            errors.extend(cost[rows, cols])
    return np.array(errors), reported, visible


def wait_for(read: Any, done: Any, timeout: float, what: str, every: float = 0.1) -> Any:
    """``read()`` until ``done(value)``: a liveness bound (generous: the machine may be
    loaded), not a timing assertion."""
    deadline = time.monotonic() + timeout
    while True:
        value = read()
        if done(value):
            return value
        assert time.monotonic() < deadline, f"{what}: {value}"
        time.sleep(every)


def wait_while_progressing(
    read: Any, done: Any, progress: Any, stall: float, what: str, every: float = 0.1
) -> Any:
    """``read()`` until ``done(value)``, for as long as ``progress(value)`` keeps changing: for
    work of a fixed size whose pace is the machine's load, a liveness bound on a stall (nothing
    moved for ``stall`` seconds), never on how long the whole work takes."""
    moved = time.monotonic()
    last = object()
    while True:
        value = read()
        if done(value):
            return value
        now = progress(value)
        if now != last:
            last, moved = now, time.monotonic()
        assert time.monotonic() - moved < stall, f"{what} (no progress in {stall:g} s): {value}"
        time.sleep(every)


def interrupt(proc: subprocess.Popen) -> None:
    """Ctrl-C, as a user stops a daemon (killed when it does not stop within 20 s)."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
