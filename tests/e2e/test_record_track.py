"""`momloc record`, `momloc track` and `momloc simulate --record` as a user runs them:
subprocesses of ``python -m service.cli`` on this worktree's code, files checked afterwards."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from capture.recording import Recording, RecordingWriter
from capture.rig import FrameSet
from capture.worker import Frame
from models.simulate import make_scene, simulate
from service.cli import main
from service.demo import DEMO_PRESET, DEMO_SEED
from service.offline.record import record_scene
from service.settings import DEMO_MODEL_DIR

pytestmark = pytest.mark.timeout(180)
ROOT = Path(__file__).resolve().parents[2]
SNAPSHOT_KEYS = {"v", "seq", "t", "people", "frame"}
PERSON_KEYS = {"id", "x", "y", "vx", "vy", "confidence", "cameras"}
OPTIONAL_PERSON_KEYS = {"outside", "posture", "posture_confidence"}  # sent when they apply
METRIC_KEYS = {"precision", "recall", "mota", "id_switches", "mean", "median", "acc@0.3"}


def momloc(*args: object, timeout: float = 150) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOMLOC_")}
    env["PYTHONPATH"] = str(ROOT)
    return subprocess.run(
        [sys.executable, "-m", "service.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=ROOT,
    )


def ok(*args: object) -> subprocess.CompletedProcess:
    result = momloc(*args)
    assert result.returncode == 0, result.stderr[-2000:]
    return result


def read_positions(path: Path) -> list[dict]:
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    for row in rows:
        assert set(row) == SNAPSHOT_KEYS and row["v"] == 1
        for person in row["people"]:
            assert set(person) - OPTIONAL_PERSON_KEYS == PERSON_KEYS
            assert ("posture" in person) == ("posture_confidence" in person)
    assert [r["frame"] for r in rows] == list(range(len(rows)))
    return rows


def room_share(rows: list[dict]) -> tuple[int, float]:
    """Positions reported, and the share of them inside the 10 x 10 m demo room (+ 1 m)."""
    xy = np.array([[p["x"], p["y"]] for r in rows for p in r["people"]]).reshape(-1, 2)
    inside = np.all((xy > -1.0) & (xy < 11.0), axis=1)
    return len(xy), float(inside.mean()) if len(xy) else 0.0


def test_record_the_synthetic_scene_then_track_it(tmp_path):
    config = tmp_path / "synthetic.yaml"
    config.write_text(
        "cameras:\n  - {type: synthetic, index: 0}\n  - {type: synthetic, index: 1}\n"
        f"synthetic: {{preset: {DEMO_PRESET}, seed: {DEMO_SEED}, people: 3, fps: 15}}\n"
    )
    rec = tmp_path / "rec"
    result = ok("record", "--config", config, "--out", rec, "--seconds", 3)
    assert "frame sets in" in result.stdout and "recording" in result.stderr  # progress line
    recording = Recording.open(rec)
    assert recording.num_cameras == 2 and recording.image_sizes == [(640, 480)] * 2
    assert len(recording) >= 5, "the rig delivered almost nothing in 3 s"
    stamps = [s.timestamp for _, s in recording.frame_sets()]
    times = [t for t in stamps if t is not None]
    assert len(times) == len(stamps)
    assert times == sorted(times)  # capture times, in the order the pipeline took them

    out = tmp_path / "positions.jsonl"
    result = ok("track", rec, "--model", DEMO_MODEL_DIR, "--out", out)
    assert "tracking" in result.stderr and "sets/s" in result.stderr  # progress bar, summary
    rows = read_positions(out)
    assert len(rows) == len(recording)
    assert [r["t"] for r in rows] == pytest.approx(times)
    count, inside = room_share(rows)
    assert count >= len(rows), "fewer positions than frame sets for 3 walking people"
    assert inside >= 0.9


def test_ctrl_c_ends_an_open_ended_recording_with_its_manifest(tmp_path):
    config = tmp_path / "synthetic.yaml"
    config.write_text("cameras:\n  - {type: synthetic, index: 0}\n")
    rec = tmp_path / "rec"
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOMLOC_")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "service.cli", "record", "--config", str(config), "--out", str(rec)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**env, "PYTHONPATH": str(ROOT)},
    )
    try:
        # the progress line names the frame sets; wait until a few were written
        seen = ""
        assert proc.stderr is not None
        while "5 frame sets" not in seen and proc.poll() is None:
            seen += proc.stderr.read(1)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    assert "frame sets in" in stdout
    assert len(Recording.open(rec)) >= 5


def write_clips(folder: Path, frames: int = 30) -> list[Path]:
    """Two cameras' views of the demo scene as plain MJPG .avi files (no timestamps)."""
    scene = make_scene(DEMO_PRESET, seed=DEMO_SEED, people=3, fps=15)
    paths = []
    for k in range(2):
        path = folder / f"clip{k}.avi"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 15, (640, 480))
        for i in range(frames):
            writer.write(scene.render(i, k))
        writer.release()
        paths.append(path)
    return paths


def test_record_video_files_then_replay_the_recording_and_track(tmp_path):
    clip0, clip1 = write_clips(tmp_path)
    config = tmp_path / "files.yaml"
    config.write_text(
        f"cameras:\n  - {{type: file, path: {clip0}}}\n  - {{type: file, path: {clip1}}}\n"
    )
    rec = tmp_path / "rec"
    ok("record", "--config", config, "--out", rec, "--seconds", 2)
    recording = Recording.open(rec)
    assert [c.name for c in recording.cameras] == ["clip0.avi", "clip1.avi"]
    assert len(recording) >= 5

    # the recording itself as `type: file` cameras (folder + camera): a replay, recorded again
    replay = tmp_path / "replay.yaml"
    replay.write_text(
        f"cameras:\n  - {{type: file, path: {rec}, camera: 0}}\n"
        f"  - {{type: file, path: {rec}/cam1.avi}}\n"
    )
    again = tmp_path / "again"
    ok("record", "--config", replay, "--out", again, "--seconds", 2)
    assert len(Recording.open(again)) >= 5

    out = tmp_path / "positions.jsonl"
    ok("track", rec, "--model", DEMO_MODEL_DIR, "--out", out)
    rows = read_positions(out)
    count, inside = room_share(rows)
    assert count >= 5, "the detector found (almost) nobody in the recorded frames"
    assert inside >= 0.9
    # No check of two-camera fusion here: how many frame sets a real-time recording of video
    # files holds depends on the machine's load (a loaded CI run recorded too few for a track to
    # be confirmed by both cameras, RECOMMENDED multi_view_s). Fusion through record -> track
    # is scored against the truth, deterministically, in the simulate --record test below.


def test_simulate_record_then_track_against_the_truth(tmp_path):
    data, rec = tmp_path / "scene.npz", tmp_path / "rec"
    frames = 60
    ok("simulate", "--preset", DEMO_PRESET, "--seed", DEMO_SEED, "--people", 3,
       "--frames", frames, "--out", data, "--record", rec)  # fmt: skip
    recording = Recording.open(rec)
    assert len(recording) == frames and [c.frames for c in recording.cameras] == [frames] * 2
    out = tmp_path / "positions.jsonl"
    assert (rec / "truth.npz").is_file()  # everyone in view, beside the frames
    result = ok("track", rec, "--model", DEMO_MODEL_DIR, "--out", out,
                "--truth", rec / "truth.npz", "--json")  # fmt: skip
    metrics = json.loads(result.stdout)  # stdout is exactly one JSON object
    assert METRIC_KEYS | {"jitter_m", "gates"} <= set(metrics)
    assert metrics["frames"] == frames and metrics["gate_m"] == 0.5
    # measured 2026-12-01 on these 60 frames: recall 88.9 %, precision 78.0 %, MOTA 63.9 %,
    # mean 0.078 m (bounds with margin for other trackers and detector thresholds)
    assert metrics["recall"] > 70.0
    assert metrics["precision"] > 55.0
    assert metrics["mota"] > 30.0
    assert metrics["mean"] < 0.2
    assert metrics["gates"]["1"]["recall"] >= metrics["recall"]
    assert len(read_positions(out)) == frames


def test_track_a_dataset_files_boxes(tmp_path):
    data = tmp_path / "scene.npz"
    ok("simulate", "--preset", DEMO_PRESET, "--seed", 3, "--frames", 300, "--out", data)
    out = tmp_path / "positions.csv"
    result = ok("track", "--detections", data, "--model", DEMO_MODEL_DIR, "--out", out,
                "--csv", "--truth", data, "--json")  # fmt: skip
    metrics = json.loads(result.stdout)
    # measured 2026-12-01 (simulated nanodet-like boxes, the daemon's tracker settings): recall
    # 75.2 %, precision 57.4 %, MOTA 18.1 %, mean 0.21 m; service.offline.stream_eval.run_stream
    # with the same tracker on the same scene gives 68 / 49 / -5 % against everyone in view
    assert metrics["recall"] > 60.0 and metrics["precision"] > 40.0 and metrics["mean"] < 0.35
    with out.open(newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["t", "frame", "id", "x", "y", "vx", "vy", "cameras"]
    assert len(rows) > 300
    frames = [int(r[1]) for r in rows[1:]]
    assert frames == sorted(frames) and max(frames) <= 299
    assert {c for r in rows[1:] for c in r[7].split()} <= {"0", "1"}


def test_bad_inputs_are_one_line_and_exit_2(tmp_path, capsys):
    """The first three as a user sees them (a process: no traceback anywhere), the rest through
    the same ``main`` in this process (a process start costs seconds on the loaded box)."""
    three = simulate("office-3cam", 30).dataset.save(tmp_path / "three.npz")
    not_model = tmp_path / "not-a-model"
    not_model.mkdir()
    rec = tmp_path / "rec"
    record_scene(simulate(DEMO_PRESET, 3).scene, 3, rec, progress=False)
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "cam0.avi").write_bytes(b"")
    small = tmp_path / "small"
    with RecordingWriter(small, ["a", "b"]) as writer:
        picture = np.zeros((48, 64, 3), np.uint8)
        writer.add(FrameSet([Frame(k, picture, 1.0, 0) for k in range(2)], skew=0.0))
    out = tmp_path / "p.jsonl"
    cases = [
        (["track", tmp_path / "missing", "--model", DEMO_MODEL_DIR, "--out", out],
         "no such recording folder"),
        (["track", rec, "--model", not_model, "--out", out], "not a model directory"),
        (["track", "--detections", three, "--model", DEMO_MODEL_DIR, "--out", out],
         "model expects 2 cameras"),
        (["track", small, "--model", DEMO_MODEL_DIR, "--out", out],
         "model expects 640x480 images from camera 0"),
        (["track", unfinished, "--model", DEMO_MODEL_DIR, "--out", out], "no manifest.json"),
        (["track", rec, "--model", DEMO_MODEL_DIR, "--out", out, "--truth", three],
         "the file has 3 cameras"),
        (["track", rec, "--model", DEMO_MODEL_DIR, "--out", out, "--json"], "--json needs"),
        (["track", rec, "--model", DEMO_MODEL_DIR, "--out", out, "--smooth-s", -1], "--smooth-s"),
        (["track", "--model", DEMO_MODEL_DIR, "--out", out], "either RECORDING_DIR"),
        (["record", "--config", tmp_path / "none.yaml", "--out", tmp_path / "r2"],
         "cannot read settings file"),
        (["simulate", "--frames", 3, "--out", tmp_path / "e.npz", "--record", rec],
         "exists and is not an empty folder"),
    ]  # fmt: skip
    for i, (args, message) in enumerate(cases):
        if i < 3:
            result = momloc(*args)
            code, stderr = result.returncode, result.stderr
        else:
            code = main([str(a) for a in args])
            stderr = capsys.readouterr().err
        lines = stderr.strip().splitlines()
        assert code == 2, (args, stderr[-1500:])
        assert len(lines) == 1 and message in lines[0], (args, lines)
        assert not out.exists() and not (tmp_path / "e.npz").exists()  # nothing half-written
