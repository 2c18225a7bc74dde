"""Fingerprints of small runs of every Maze variant on :class:`~tests.fakes.BitmapDomain`.

``tests/core/test_golden.py`` checks that the outer loop still produces exactly these: the same archive
(cells, objectives, solutions) and the same per-iteration metrics, bit for bit, so a refactor of the
loop cannot change what a seed finds. After a change that is *meant* to change results, rewrite the
fixture with ``python -m tests.core.golden`` and say why in the commit.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from dsage_ray.config import RunConfig, variants
from dsage_ray.core.runner import DSAGE, torch_threads
from tests.fakes import SMALL_RUN, BitmapDomain

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "golden_runs.json"
SEEDS = (0, 1)


def fingerprint(variant: str, seed: int) -> dict[str, object]:
    """Runs ``variant`` with ``seed`` to its budget; the digest of its archive and its untimed metrics."""
    runner = DSAGE(config=RunConfig.build({**SMALL_RUN, "variant": variant, "seed": seed}), domain=BitmapDomain())
    with torch_threads(1):
        runner.run()
    data = runner.archive.data()
    order = np.argsort(data["index"])
    archive = hashlib.sha256()
    for key in ("index", "objective", "measures", "solution"):
        archive.update(np.ascontiguousarray(np.asarray(data[key])[order]).tobytes())
    untimed = [{key: value for key, value in row.items() if "time" not in key} for row in runner.history]
    return {"archive_sha256": archive.hexdigest(), "elites": int(len(order)),
            "qd_score": [row["qd_score"] for row in runner.history],
            "metrics_sha256": hashlib.sha256(json.dumps(untimed, sort_keys=True).encode()).hexdigest()}


def all_fingerprints() -> dict[str, dict[str, object]]:
    return {f"{variant}/seed{seed}": fingerprint(variant, seed) for variant in variants("maze") for seed in SEEDS}


if __name__ == "__main__":
    FIXTURE.write_text(json.dumps(all_fingerprints(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {FIXTURE}")
