"""`make bench-real`: the CMC room, "set up with 3 people, serve 10", through the daemon's chain.

Data: Ong, Vo, Vo, Kim, Nordholm, "A Bayesian Filter for Multi-view 3D Multi-object Tracking
with Occlusion Handling", IEEE TPAMI 2020 (``../shared/data/cmc``; evaluation only, read from
``--data``, never copied). A real 4-camera room with real Faster R-CNN boxes and true floor
positions: models are trained with the product's ``models.mom.training.train`` on CMC1 (3 people;
the real boxes paired with the true positions, ``bench.real.cmc_setup``), then CMC2's raw boxes (10
people, every box of every camera, boxes of nobody included) are served by the daemon's own
``Pipeline.process`` and scored (``bench.real.cmc_chain``, ``bench.real.cmc_score``).

For fast iteration on the chain (association, tracker, validity gate)::

    from bench.real.cmc import evaluate
    result = evaluate(".cache/real_cmc/model_dense_<key>", "CMC2")  # or train_models()["dense"]
    print(result["moda"], result["mota"], result["fp_breakdown"])

Served variants: ``dense`` and ``marks9`` (``bench.real.cmc_setup``) on CMC2 and, in-sample,
CMC1; ``dense_encoder`` (the dense model served by its encoder alone) and
``dense_people_only`` (fed only the boxes of true people: a perfect validity gate) and
``dense_true_association`` (the association replaced by the true one) on CMC2.

Figures live in ``bench/results/real_cmc.md`` (and ``real_cmc.json``, read by the simulator's
validation: keep its keys).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from bench.real import cmc_data
from bench.real.cmc_chain import Ground, TrueAssociation, score, serve
from bench.real.cmc_setup import (
    ROOT,
    VARIANTS,
    encoder_only,
    labelled_dataset,
    replay_path,
    trained_model,
)

DEFAULT_DATA = ROOT.parent / "shared" / "data"
SEQUENCES = ("CMC2", "CMC1")


def evaluate(
    model_dir: str | Path,
    sequence: str = "CMC2",
    data: str | Path = DEFAULT_DATA,
    *,
    people_only: bool = False,
    true_association: bool = False,
) -> dict[str, Any]:
    """Serve ``sequence``'s raw boxes with the model in ``model_dir`` through the daemon's chain
    and score it (per-frame ``moda``, ``precision``, ``recall``, ``modp``, ``matched_mean_m``,
    their split ``*_by_cameras``, ``fp_breakdown`` / ``fn_breakdown``; streamed ``mota``,
    ``idf1``, ``id_switches``, ``acc_0_3``). Takes 1-2 min for CMC2 on a busy core; the replay
    and the evaluation pairing are rebuilt each call from ``data`` (cheap).

    ``people_only``: serve only the boxes the evaluation pairing gives to a true person (the
    boxes of nobody removed), the bound a perfect validity gate would reach.
    ``true_association``: the association stage replaced by the evaluation pairing
    (``bench.real.cmc_chain.TrueAssociation``): what the tracker makes of perfect clusters."""
    data = Path(data)
    replay = replay_path(data, sequence)
    ground = Ground.build(data, sequence, replay)
    if people_only:
        replay = ground.people_replay(replay.with_name(f"{replay.stem}_people.npz"))
        ground = Ground.build(data, sequence, replay)
    oracle = TrueAssociation(ground) if true_association else None
    return score(ground, serve(Path(model_dir), replay, oracle))


def train_models(data: str | Path = DEFAULT_DATA) -> dict[str, Path]:
    """The ``dense`` and ``marks9`` models trained on CMC1 (cached; see bench.real.cmc_setup)."""
    dataset = labelled_dataset(Path(data), "CMC1")
    return {variant: trained_model(dataset, variant) for variant in VARIANTS}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder holding cmc/")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="Markdown report (default: bench/results/real_cmc.md)",
    )
    args = parser.parse_args(argv)
    if not cmc_data.available(args.data):
        print(f"bench-real: no CMC data under {args.data}: skipped")
        return 0
    from bench.real import cmc_report as real_cmc_report

    start = time.perf_counter()
    models = train_models(args.data)
    served = {**models, "dense_encoder": encoder_only(models["dense"])}
    results: dict[str, Any] = {}
    for variant, model_dir in served.items():
        for sequence in SEQUENCES if variant in VARIANTS else SEQUENCES[:1]:
            print(f"bench-real: {variant} on {sequence} ...", file=sys.stderr, flush=True)
            results.setdefault(variant, {})[sequence] = evaluate(model_dir, sequence, args.data)
    print("bench-real: dense on CMC2, boxes of people only ...", file=sys.stderr, flush=True)
    results["dense_people_only"] = {
        "CMC2": evaluate(models["dense"], "CMC2", args.data, people_only=True)
    }
    print("bench-real: dense on CMC2, true association ...", file=sys.stderr, flush=True)
    results["dense_true_association"] = {
        "CMC2": evaluate(models["dense"], "CMC2", args.data, true_association=True)
    }
    results["anchors"] = real_cmc_report.anchors(args.data, models)
    results["models"] = {name: real_cmc_report.model_facts(path) for name, path in served.items()}
    out = real_cmc_report.write(results, args.out, time.perf_counter() - start, argv)
    print(f"bench-real: wrote {out} and its .json")
    print(json.dumps({v: results[v]["CMC2"]["moda"] for v in VARIANTS}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
