"""The self-label store: kept across restarts, bounded on disk, written atomically, per room."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import common.atomic
from service.learning.labels import LabelBatch
from service.learning.store import DEFAULT_MAX_BYTES, SelfLabelStore, room_key
from service.settings import LearningSettings
from tests.service.learning.frames import SIZES


def batch(n: int, t0: float = 0.0, seed: int = 0) -> LabelBatch:
    rng = np.random.default_rng(seed)
    return LabelBatch(
        t=t0 + np.arange(n, dtype=np.float64),
        track=np.arange(n, dtype=np.int64) % 3,
        world=rng.uniform(0, 10, (n, 2)).astype(np.float32),
        covariance=np.tile(np.eye(2, dtype=np.float32) * 0.01, (n, 1, 1)),
        boxes=rng.uniform(0, 400, (n, 2, 4)).astype(np.float32),
        keypoints=rng.uniform(0, 400, (n, 2, 17, 3)).astype(np.float32),
        cost=np.full(n, 5.0, np.float32),
    )


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_labels_are_written_in_chunks_and_read_back_after_a_restart(tmp_path: Path) -> None:
    clock = Clock()
    store = SelfLabelStore(tmp_path, SIZES, flush_rows=50, flush_s=5.0, clock=clock)
    store.add(batch(30))
    assert store.count == 30 and not list(tmp_path.glob("*.npz"))  # pending, in memory
    clock.now = 6.0
    store.add(batch(5, t0=30))  # the oldest pending row has waited flush_s: written
    assert len(list(tmp_path.glob("labels-*.npz"))) == 1
    store.add(batch(60, t0=35))  # flush_rows reached: written at once
    assert len(list(tmp_path.glob("labels-*.npz"))) == 2
    again = SelfLabelStore(tmp_path, SIZES)
    assert again.count == 95
    loaded = again.load()
    assert loaded is not None
    np.testing.assert_array_equal(loaded.t, np.arange(95.0))
    np.testing.assert_array_equal(loaded.keypoints[:30], batch(30).keypoints)
    later = again.load(since=90.0)
    assert later is not None and later.n == 5


def test_the_store_stays_under_its_cap_by_dropping_the_oldest_labels(tmp_path: Path) -> None:
    store = SelfLabelStore(tmp_path, SIZES, flush_rows=100, max_bytes=10**9)
    store.add(batch(100, seed=1))
    one_chunk = store.stored_bytes
    store = SelfLabelStore(tmp_path, SIZES, flush_rows=100, max_bytes=int(3.5 * one_chunk))
    for i in range(1, 10):
        store.add(batch(100, t0=100.0 * i, seed=i + 1))
        assert store.stored_bytes <= 3.5 * one_chunk
    assert len(list(tmp_path.glob("labels-*.npz"))) == 3
    loaded = store.load()
    assert loaded is not None and loaded.t.min() == 700.0  # the newest three chunks
    assert store.count == 300


def test_a_failed_write_leaves_no_partial_chunk_and_keeps_the_labels(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store = SelfLabelStore(tmp_path, SIZES, flush_rows=10)
    store.add(batch(10))

    def full_disk(path, produce, mode=0o644):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("service.learning.store.atomic_write", full_disk)
    store.add(batch(10, t0=10))
    assert store.write_error is not None and "No space left" in store.write_error
    assert len(list(tmp_path.glob("labels-*.npz"))) == 1 and not list(tmp_path.glob(".*tmp"))
    assert store.count == 20  # the failed rows wait for the next flush
    monkeypatch.setattr("service.learning.store.atomic_write", common.atomic.atomic_write)
    store.flush()
    assert store.write_error is None and SelfLabelStore(tmp_path, SIZES).count == 20


def test_a_chunk_is_written_through_the_atomic_writer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    written: list[Path] = []
    real = common.atomic.atomic_write

    def spy(path, produce, mode=0o644):
        written.append(Path(path))
        return real(path, produce, mode)

    monkeypatch.setattr("service.learning.store.atomic_write", spy)
    store = SelfLabelStore(tmp_path, SIZES, flush_rows=1)
    store.add(batch(3))
    assert [p.name for p in written] == ["labels-000001.npz"]


def test_a_damaged_chunk_is_ignored(tmp_path: Path) -> None:
    SelfLabelStore(tmp_path, SIZES, flush_rows=5).add(batch(5))
    (tmp_path / "labels-000002.npz").write_bytes(b"not a zip")
    store = SelfLabelStore(tmp_path, SIZES)
    assert store.count == 5
    loaded = store.load()
    assert loaded is not None and loaded.n == 5


def test_a_model_learned_by_the_room_keeps_its_room() -> None:
    first = {"num_cameras": 2, "metrics": {"val_mean_m": 0.2}}
    room = room_key(first)
    assert room_key(dict(first)) == room
    assert room_key({**first, "metrics": {"val_mean_m": 0.1}}) != room  # new marks: new room
    assert room_key({"num_cameras": 2, "learning": {"room": room}}) == room


def test_the_default_cap_is_the_settings_default_in_the_units_health_reports() -> None:
    """Issue 26 caps the store at 50 MB; health reports megabytes of 10^6 bytes, and a library
    default of 50 MiB showed 52.4 there."""
    assert DEFAULT_MAX_BYTES == LearningSettings().max_mb * 1e6 <= 50e6
