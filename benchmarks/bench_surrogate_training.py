"""How surrogate training settings predict the agent: a DSAGE run's own data, replayed.

A finished run's checkpoint holds every level it evaluated, in order, with the agent's real
measures, and its held-out levels. For each training setting this replays the run's outer loop
offline: before outer iteration ``k`` the surrogate (one model and one Adam, persisting, as in a
run) trains on what iterations ``1..k-1`` evaluated, then predicts the batch iteration ``k``
evaluated and the held-out levels. It prints, per setting and iteration, the mean absolute error
of each measure on that batch and on the held-out levels, the held-out Spearman ρ, and the
training seconds, so settings compare on the same levels and the same seconds.

The batches were selected by the run's own surrogate, so a replayed setting is scored on levels
another model chose: a fair, not identical, stand-in for the error a run with that setting sees
(confirm a choice with a real run and its ``mae_*`` / ``holdout_*`` metrics).

    python benchmarks/bench_surrogate_training.py RUN_FOLDER \
        [--setting NAME:key=value,key=value ...] [--threads 1] [--json out.json]

Keys are ``surrogate.*`` keys without the prefix (``epochs=30,batch_size=64,channels=16``), any
dotted config key (``maze.path_channels=true``: Maze levels are re-encoded from their wall channel) or
``seed`` (the surrogate's initialisation and minibatch order; default the run's); without ``--setting``
the run's own settings are replayed.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def parse_setting(text: str) -> tuple[str, dict]:
    """``"name:epochs=30,lr=3e-4"`` → ``("name", {"surrogate.epochs": 30, "surrogate.lr": 0.0003})``."""
    from dsage_ray.config import parse_override

    import re

    name, _, body = text.partition(":")
    parts = [item for item in re.split(r",(?![^\[]*\])", body) if item]  # commas inside [...] belong to a list
    if not name or any("=" not in item for item in parts):
        raise SystemExit(f"--setting {text!r}: expected NAME:key=value,key=value")
    items = [item if "." in item.partition("=")[0] or item.startswith("seed=") else f"surrogate.{item}"
             for item in parts]
    return name, dict(parse_override(item) for item in items)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a finished run folder (holding its checkpoint)")
    parser.add_argument("--setting", action="append", default=[], help="NAME:key=value,… (repeatable)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (the cpu preset trains on 1)")
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args(argv)

    import numpy as np
    import torch
    from scipy import stats

    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.domains import build_domain
    from dsage_ray.surrogate import Surrogate, SurrogateDataset
    from dsage_ray.surrogate.dataset import Targets
    from dsage_ray.surrogate.models import pad_to_power_of_two

    torch.set_num_threads(args.threads)
    state = load_checkpoint(args.run / CHECKPOINT_NAME)
    config = RunConfig.build(state["config"])
    if state.get("dataset") is None or not state.get("holdout"):
        raise SystemExit(f"{args.run}: needs a surrogate run with held-out levels (experimental.holdout_levels > 0)")
    domain = build_domain(config)
    num_measures = len(domain.measure_names)
    stored = SurrogateDataset(level_shape=tuple(state["dataset"]["level_shape"]), num_measures=num_measures,
                              occupancy_shape=domain.occupancy_shape)
    stored.load_state_dict(state["dataset"])
    # Iteration boundaries in dataset rows: failed evaluations never entered the dataset.
    failed_at = sorted(int(f["eval_index"]) for f in state["failures"])
    ends = [int(m["evals"]) - sum(i < int(m["evals"]) for i in failed_at) for m in state["history"]]
    holdout = Targets.from_results(state["holdout"]["results"], num_measures=num_measures,
                                   occupancy_shape=domain.occupancy_shape)

    settings = [parse_setting(text) for text in args.setting] or [("run", {})]
    report: dict = {"run": str(args.run), "threads": args.threads, "iterations": len(ends), "settings": {}}
    for name, overrides in settings:
        setting = RunConfig.build({**config.to_flat(), **overrides})
        setting_domain = build_domain(setting)

        def encode(solutions) -> np.ndarray:
            return pad_to_power_of_two(setting_domain.encode(solutions), pad_channel=setting_domain.encoding_pad_channel)

        levels = stored.levels()
        if setting.domain == "maze" and setting_domain.encoding_channels != levels.shape[1]:
            from dsage_ray.domains.maze.encoding import WALL

            levels = encode(levels[:, WALL].reshape(len(levels), -1))
        holdout_levels = encode(state["holdout"]["solutions"])

        def dataset_until(end: int) -> SurrogateDataset:
            dataset = SurrogateDataset(level_shape=levels.shape[1:], num_measures=num_measures,
                                       occupancy_shape=domain.occupancy_shape)
            dataset.load_state_dict({"levels": np.packbits(levels[:end].reshape(end, -1).astype(bool), axis=1),
                                     "objective": stored.objective[:end], "measures": stored.measures[:end],
                                     "occupancy": stored.occupancy[:end], "level_shape": levels.shape[1:]})
            return dataset

        surrogate = Surrogate.for_domain(setting_domain, config=setting.surrogate, seed=setting.seed)
        rows = []
        for k in range(1, len(ends)):
            tic = time.perf_counter()
            losses = surrogate.train(dataset_until(ends[k - 1]))
            train_s = time.perf_counter() - tic
            batch = slice(ends[k - 1], ends[k])
            predicted = surrogate.predict(levels[batch]).measures
            on_holdout = surrogate.predict(holdout_levels).measures
            row = {"iteration": k + 1, "trained_on": ends[k - 1], "train_s": round(train_s, 1),
                   "epochs": int(losses["epochs"])}
            for i, measure in enumerate(domain.measure_names):
                row[f"mae_{measure}"] = round(float(np.abs(predicted[:, i] - stored.measures[batch, i]).mean()), 1)
                row[f"holdout_mae_{measure}"] = round(float(np.abs(on_holdout[:, i] - holdout.measures[:, i]).mean()), 1)
                row[f"holdout_spearman_{measure}"] = round(float(stats.spearmanr(on_holdout[:, i],
                                                                                 holdout.measures[:, i]).statistic), 3)
            rows.append(row)
            print(f"{name:>18}  " + "  ".join(f"{key} {value}" for key, value in row.items()), flush=True)
        report["settings"][name] = {"overrides": overrides, "iterations": rows,
                                    "train_s_total": round(sum(r["train_s"] for r in rows), 1)}
    print()
    measure = domain.measure_names[-1]
    print(f"per setting, the last measure ({measure}): selected-batch MAE by iteration | held-out ρ by iteration "
          f"| training seconds")
    for name, result in report["settings"].items():
        rows = result["iterations"]
        print(f"{name:>18}  MAE {' '.join(str(r[f'mae_{measure}']) for r in rows)}  |  "
              f"ρ {' '.join(str(r[f'holdout_spearman_{measure}']) for r in rows)}  |  {result['train_s_total']} s")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return report


if __name__ == "__main__":
    main()
