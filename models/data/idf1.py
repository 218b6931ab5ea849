"""IDF1 (Ristani et al., ECCV 2016 workshops): how long each person keeps one served id.

Where MOTA counts an id switch once, IDF1 asks the global question a client asks: if every
true person is given the one served id that follows them longest (a one-to-one matching of
true ids to served ids over the whole stream, maximising the frames where the two are within
``gate_m`` of each other), which share of all true and served positions agree with it?

``idtp``   frames where a true person and their assigned served id are within the gate
``idfp``   served positions not counted in ``idtp``; ``idfn`` true positions not in ``idtp``
``idf1``   ``2 idtp / (2 idtp + idfp + idfn)`` in percent; ``idp``, ``idr`` the precision and
           recall of the same counts.

Example::

    print(identity_scores(frames)["idf1"])  # frames: models.data.stream_metrics.StreamFrame
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from models.data.stream_metrics import StreamFrame


def identity_scores(frames: Sequence[StreamFrame], gate_m: float = 0.5) -> dict[str, float]:
    """``idf1``, ``idp``, ``idr`` (percent) and the counts (see the module docstring)."""
    together: Counter[tuple[int, int]] = Counter()
    truth_total = served_total = 0
    for f in frames:
        truth_xy = np.asarray(f.truth_xy, np.float64).reshape(-1, 2)
        served_xy = np.asarray(f.served_xy, np.float64).reshape(-1, 2)
        truth_total += len(truth_xy)
        served_total += len(served_xy)
        if not len(truth_xy) or not len(served_xy):
            continue
        near = np.linalg.norm(truth_xy[:, None] - served_xy[None], axis=2) <= gate_m
        for r, c in zip(*np.nonzero(near), strict=True):
            together[(int(f.truth_ids[r]), int(f.served_ids[c]))] += 1
    idtp = 0
    if together:
        truth_ids = sorted({o for o, _ in together})
        served_ids = sorted({h for _, h in together})
        gain = np.zeros((len(truth_ids), len(served_ids)))
        ti = {o: i for i, o in enumerate(truth_ids)}
        si = {h: j for j, h in enumerate(served_ids)}
        for (o, h), n in together.items():
            gain[ti[o], si[h]] = n
        rows, cols = linear_sum_assignment(-gain)
        idtp = int(gain[rows, cols].sum())
    idfp, idfn = served_total - idtp, truth_total - idtp
    denominator = 2 * idtp + idfp + idfn
    return {
        "idf1": 100.0 * 2 * idtp / denominator if denominator else float("nan"),
        "idp": 100.0 * idtp / served_total if served_total else float("nan"),
        "idr": 100.0 * idtp / truth_total if truth_total else float("nan"),
        "idtp": idtp,
        "idfp": idfp,
        "idfn": idfn,
    }
