"""The room learns while it serves: the real daemon on the synthetic scene collects self-labels,
/v1/health counts them, and they are on disk in the model's room folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from service.learning.store import SelfLabelStore
from tests.e2e.server import running_server, wait_for

pytestmark = pytest.mark.timeout(240)


def test_health_counts_self_labels_as_people_walk(tmp_path: Path) -> None:
    with running_server(
        lockstep=True, data_dir=tmp_path, learning={"enabled": True, "min_interval_s": 0.2}
    ) as srv:
        assert srv.get("/v1/health").json()["learning"]["enabled"] is True
        first = wait_for(
            lambda: srv.get("/v1/health").json()["learning"],
            lambda learning: learning["self_labels"] > 0,
            180,
            "no self-labels",
        )
        grown = wait_for(
            lambda: srv.get("/v1/health").json()["learning"],
            lambda learning: learning["self_labels"] > first["self_labels"] + 20,
            180,
            "self-labels stopped growing",
        )
        assert grown["frames_seen"] > 0 and grown["room"]
        room = tmp_path / "learning" / grown["room"]
    # stopped: the pending labels are written; each is a well-seen person in the room
    store = SelfLabelStore(room, np.array([[640, 480], [640, 480]]))
    assert store.count >= grown["self_labels"]
    labels = store.load()
    assert labels is not None
    assert labels.views().sum(axis=1).min() >= 2
    assert (labels.std_m() <= 0.15).all()
    assert ((labels.world >= -1.0) & (labels.world <= 11.0)).all()  # the 10 m demo room
