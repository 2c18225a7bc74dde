"""Can the surrogate tell which levels will be dear to evaluate? The question behind a cost-aware selection.

Reads a finished expected-gain run whose ``selection.cost_measure`` is a work count (e.g. Mario's
``search_iterations``), so that every evaluated pick's work is in its checkpoint. The checkpoint's surrogate
was trained before the last batch of picks came back, so that batch is unseen. Prints, for the levels it
trained on and for that unseen batch:

- how much work their evaluations took (mean, and the share above 10× the median of the first levels);
- how well the work correlates with what the surrogate predicts of a level: each measure, the objective and,
  for a surrogate that predicts occupancy, its sum (e.g. Mario's ticks).

Usage:
    python benchmarks/bench_cost_prediction.py RUN_FOLDER
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished run folder (config.json, checkpoint.dsage)")
    args = parser.parse_args(argv)

    import torch

    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.domains import build_domain
    from dsage_ray.surrogate import Surrogate

    torch.set_num_threads(1)
    config = RunConfig.from_file(args.run / "config.json")
    state = load_checkpoint(args.run / CHECKPOINT_NAME)
    work = np.asarray((state.get("pick_errors") or {}).get("work", []), np.float64)
    if not config.selection.expected_gain or not len(work) or np.isnan(work).all():
        parser.error(f"{args.run} recorded no work counts: run it with selection.expected_gain and a "
                     "selection.cost_measure that names one of the domain's work counts")
    domain = build_domain(config)
    surrogate = Surrogate.for_domain(domain, config=config.surrogate, seed=0)
    surrogate.load_state_dict(state["surrogate"])
    dataset = surrogate.make_dataset()
    dataset.load_state_dict(state["dataset"])
    last = state["history"][-1]
    unseen = int(last["evaluated_this_iteration"] - last.get("failed_evals", 0))
    # The pick errors are the dataset's latest samples, in the same order.
    kept = min(len(work), len(dataset))
    positions = np.arange(len(dataset) - kept, len(dataset))
    work = work[-kept:]
    prediction = surrogate.predict(dataset.levels(positions))
    predicted = {"objective": prediction.objective}
    predicted |= {name: prediction.measures[:, i] for i, name in enumerate(domain.measure_names)}
    if prediction.occupancy is not None:
        predicted["occupancy sum"] = prediction.occupancy.reshape(kept, -1).sum(axis=1)
    dear = 10 * np.median(work[:kept - unseen]) if kept > unseen else np.inf
    print(f"{args.run}: {config.selection.cost_measure} of {kept} evaluated levels; the last {unseen} were picked "
          "by the surrogate in the checkpoint and never trained on")
    for label, rows in (("trained on", slice(0, kept - unseen)), ("unseen picks", slice(kept - unseen, kept))):
        part = work[rows]
        if not len(part):
            continue
        correlations = ", ".join(
            f"{name} {np.corrcoef(values[rows], part)[0, 1]:+.3f}" if np.std(values[rows]) > 0 and np.std(part) > 0
            else f"{name} (constant)" for name, values in predicted.items())
        print(f"  {label:12s} ({len(part)}): mean {part.mean():,.0f}, {np.mean(part > dear):.0%} above {dear:,.0f} "
              f"(10× the trained-on median); correlation with the predicted {correlations}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
