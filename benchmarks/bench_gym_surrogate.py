"""Does the paper's two-stage idea help on a parameter-space domain? Two-stage against one-stage surrogates on the
gym domain's own search levels.

Reads finished gym searches (each folder's ``checkpoint.dsage`` holds the surrogate's training data, every real
evaluation's level, objective, measures and occupancy histogram; ``config.json`` the run's surrogate settings).
For each search, on its own levels alone, ``--splits`` seeded random splits into train (``1 - --test-share``) and
test levels; on each split a two-stage surrogate (``VectorTwoStageModel``: parameters → occupancy histogram, then
parameters + histogram → objective and measures) and a one-stage one (``VectorOneStageModel``: parameters →
objective and measures) are trained from the same seed on the same train levels with the run's own surrogate
config (epochs, batch size, lr, width; only ``kind`` replaced), then scored on the split's test levels:

* Spearman ρ (``scipy.stats.spearmanr``) and MAE of the objective and of each measure;
* the two-stage model's occupancy MAE (mean over histogram cells and levels);
* training CPU seconds and prediction throughput (levels/s, the best of 5 calls on ``--predict-levels`` random
  levels, CPU time), torch on one thread.

Prints one row per (search, model): mean ± standard error over the splits; then a ``two − one`` row, the
two-stage minus one-stage difference per metric, paired over the splits (mean ± s.e. of the per-split
differences), ``*`` marking a difference beyond two standard errors, and a line naming which differences are
within two standard errors. With several searches, a last row averages the per-search differences (s.e. over the
searches). The splits of one search resample the same levels, so their s.e. understates how much a fresh search
would move the numbers; the searches are the more independent repeats.

Usage:
    python benchmarks/bench_gym_surrogate.py SEARCH_FOLDER [SEARCH_FOLDER ...] [--splits 3] [--seed 0]
    python benchmarks/bench_gym_surrogate.py tb_logs/gym_tuning_cartpole    # every finished */search under it

A parent folder takes its ``*/search`` folders that hold a surrogate dataset and whose audit finished (a
``collection/collection.json`` beside the search); the others are listed as skipped.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

KINDS = ("two_stage", "one_stage")
LABELS = {"two_stage": "two-stage", "one_stage": "one-stage"}


class BenchInputError(ValueError):
    """A folder this benchmark cannot read; the message is one line and names it."""


@dataclasses.dataclass
class SearchData:
    """The evaluated levels of one search and what is needed to train its surrogates.

    Attributes:
        name: How the tables name the search.
        levels: ``(n, P, 1, 1)`` float32 encoded levels.
        objective: ``(n,)``.
        measures: ``(n, m)``.
        occupancy: ``(n, H, W)``.
        domain: The search's domain (shapes, measure names and ranges for ``Surrogate.for_domain``).
        surrogate_config: The run's ``SurrogateConfig``.
    """

    name: str
    levels: np.ndarray
    objective: np.ndarray
    measures: np.ndarray
    occupancy: np.ndarray
    domain: Any
    surrogate_config: Any

    @property
    def measure_names(self) -> tuple[str, ...]:
        return tuple(self.domain.measure_names)

    def subset_state(self, rows: np.ndarray) -> dict[str, Any]:
        """A ``SurrogateDataset.state_dict`` of the levels at ``rows``."""
        return {"levels": self.levels[rows].reshape(len(rows), -1).astype(np.float32),
                "objective": self.objective[rows].astype(np.float64),
                "measures": self.measures[rows].astype(np.float64),
                "occupancy": self.occupancy[rows].astype(np.float32),
                "level_shape": tuple(self.levels.shape[1:])}


# ------------------------------------------------------------------------------------------- inputs


def find_searches(paths: Sequence[Path]) -> tuple[list[Path], list[str]]:
    """The search folders ``paths`` name, and one line per folder skipped under a parent.

    A path holding ``checkpoint.dsage`` is a search; otherwise its ``*/search`` folders are, those of an
    unfinished audit (no ``collection/collection.json`` beside the search) skipped.

    Raises:
        BenchInputError: A path that is neither a search folder nor the parent of one.
    """
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME

    searches, skipped = [], []
    for path in paths:
        if (path / CHECKPOINT_NAME).is_file():
            searches.append(path)
            continue
        found = sorted(folder for folder in path.glob("*/search") if (folder / CHECKPOINT_NAME).is_file())
        if not found:
            raise BenchInputError(f"{path}: no {CHECKPOINT_NAME} (not a search folder), and no */search folder "
                                  f"with one under it")
        for folder in found:
            if (folder.parent / "collection" / "collection.json").is_file():
                searches.append(folder)
            else:
                skipped.append(f"{folder}: audit not finished (no collection/collection.json)")
    return searches, skipped


def search_name(folder: Path) -> str:
    """``dsage_seed1`` for ``.../dsage_seed1/search``, else the folder's name."""
    return folder.parent.name if folder.name == "search" else folder.name


def load_search(folder: Path, overrides: dict[str, Any] | None = None) -> SearchData:
    """The surrogate dataset and config of the search in ``folder``; ``overrides`` (dotted ``surrogate.`` keys)
    change the run's surrogate config.

    Raises:
        BenchInputError: No checkpoint, a damaged one, no surrogate dataset in it (a search without surrogate),
            or levels that are not parameter vectors.
    """
    from dsage_ray.config import ConfigError, RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, CheckpointError, checkpoint_config, load_checkpoint
    from dsage_ray.domains import build_domain

    path = folder / CHECKPOINT_NAME
    if not path.is_file():
        raise BenchInputError(f"{folder}: no {CHECKPOINT_NAME} (not a search folder)")
    try:
        state = load_checkpoint(path)
        config = (RunConfig.from_file(folder / "config.json") if (folder / "config.json").is_file()
                  else checkpoint_config(path))
        if overrides:
            config = RunConfig.build({**config.to_dict(), **overrides})
    except (CheckpointError, ConfigError) as exc:
        raise BenchInputError(str(exc).splitlines()[0]) from None
    dataset = state.get("dataset")
    if dataset is None:
        raise BenchInputError(f"{folder}: no surrogate dataset in its checkpoint (a search without a surrogate; "
                              f"variant {config.variant})")
    level_shape = tuple(dataset["level_shape"])
    if tuple(level_shape[1:]) != (1, 1):
        raise BenchInputError(f"{folder}: levels of shape {level_shape}, not parameter vectors (P, 1, 1): "
                              f"a {config.domain} search, not a gym one")
    domain = build_domain(config)
    n = len(dataset["objective"])
    return SearchData(name=search_name(folder),
                      levels=np.asarray(dataset["levels"], np.float32).reshape(n, *level_shape),
                      objective=np.asarray(dataset["objective"], np.float64),
                      measures=np.asarray(dataset["measures"], np.float64),
                      occupancy=np.asarray(dataset["occupancy"], np.float32),
                      domain=domain, surrogate_config=config.surrogate)


# ------------------------------------------------------------------------------------------ scoring


def spearman(prediction: np.ndarray, truth: np.ndarray) -> float:
    """Spearman ρ; 0 for a constant prediction (it ranks nothing), NaN for constant truth (nothing to rank)."""
    from scipy import stats

    if np.ptp(truth) == 0:
        return math.nan
    if np.ptp(prediction) == 0:
        return 0.0
    return float(stats.spearmanr(prediction, truth).statistic)


def metric_names(measure_names: Sequence[str], kind: str) -> list[str]:
    """The metrics of a model, in table order."""
    names = ["objective ρ", "objective MAE"]
    for name in measure_names:
        names += [f"{name} ρ", f"{name} MAE"]
    return names + (["occupancy MAE"] if kind == "two_stage" else [])


def score(prediction, data: SearchData, rows: np.ndarray) -> dict[str, float]:
    """ρ and MAE of a ``Surrogate.predict`` result against the true values at ``rows``."""
    scores = {"objective ρ": spearman(prediction.objective, data.objective[rows]),
              "objective MAE": float(np.abs(prediction.objective - data.objective[rows]).mean())}
    for i, name in enumerate(data.measure_names):
        scores[f"{name} ρ"] = spearman(prediction.measures[:, i], data.measures[rows, i])
        scores[f"{name} MAE"] = float(np.abs(prediction.measures[:, i] - data.measures[rows, i]).mean())
    if prediction.occupancy is not None:
        scores["occupancy MAE"] = float(np.abs(prediction.occupancy - data.occupancy[rows]).mean())
    return scores


def splits(n: int, *, count: int, test_share: float, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` seeded random ``(train rows, test rows)`` splits of ``n`` levels."""
    test = int(round(n * test_share))
    if not 2 <= test <= n - 2:
        raise BenchInputError(f"{n} levels cannot be split into train and test at a test share of {test_share}")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        order = rng.permutation(n)
        out.append((np.sort(order[test:]), np.sort(order[:test])))
    return out


def build_surrogate(data: SearchData, kind: str, seed: int):
    from dsage_ray.surrogate import Surrogate

    config = dataclasses.replace(data.surrogate_config, kind=kind)
    return Surrogate.for_domain(data.domain, config=config, seed=seed)


def fit_and_score(data: SearchData, kind: str, train: np.ndarray, test: np.ndarray, *, seed: int,
                  predict_levels: np.ndarray | None = None) -> dict[str, float]:
    """Trains a ``kind`` surrogate from ``seed`` on the ``train`` rows and scores it on the ``test`` rows.

    Returns:
        The :func:`score` metrics, ``"train CPU s"``, and with ``predict_levels`` ``"predict levels/s"`` (the best
        of 5 predictions of them, CPU time).
    """
    surrogate = build_surrogate(data, kind, seed)
    dataset = surrogate.make_dataset()
    dataset.load_state_dict(data.subset_state(train))
    tic = time.process_time()
    surrogate.train(dataset)
    train_seconds = time.process_time() - tic
    result = score(surrogate.predict(data.levels[test]), data, test)
    result["train CPU s"] = train_seconds
    if predict_levels is not None:
        surrogate.predict(predict_levels)  # warm-up
        best = math.inf
        for _ in range(5):
            tic = time.process_time()
            surrogate.predict(predict_levels)
            best = min(best, time.process_time() - tic)
        result["predict levels/s"] = len(predict_levels) / max(best, 1e-9)
    return result


@dataclasses.dataclass
class SearchResult:
    """Per-split metrics of each model on one search."""

    data: SearchData
    per_split: dict[str, list[dict[str, float]]]
    train_size: int
    test_size: int

    def values(self, kind: str, metric: str) -> list[float]:
        return [split[metric] for split in self.per_split[kind] if metric in split]

    def differences(self, metric: str) -> list[float]:
        """Two-stage minus one-stage, per split."""
        return [a[metric] - b[metric] for a, b in zip(self.per_split["two_stage"], self.per_split["one_stage"])]


def evaluate_search(data: SearchData, *, count: int, test_share: float, seed: int,
                    predict_count: int = 4096) -> SearchResult:
    """Both models on ``count`` splits of the search's levels; split ``k`` seeds both models with ``seed + k``."""
    rng = np.random.default_rng(seed)
    predict_levels = (data.domain.encode(data.domain.random_solutions(predict_count, rng)) if predict_count
                      else None)
    per_split: dict[str, list[dict[str, float]]] = {kind: [] for kind in KINDS}
    parts = splits(len(data.objective), count=count, test_share=test_share, seed=seed)
    for k, (train, test) in enumerate(parts):
        for kind in KINDS:
            per_split[kind].append(fit_and_score(data, kind, train, test, seed=seed + k,
                                                 predict_levels=predict_levels if k == 0 else None))
    return SearchResult(data=data, per_split=per_split, train_size=len(parts[0][0]), test_size=len(parts[0][1]))


# ------------------------------------------------------------------------------------------- report


def spec_of(metric: str) -> str:
    if metric.endswith("ρ"):
        return ".3f"
    if metric == "occupancy MAE":
        return ".4f"
    if metric == "predict levels/s":
        return ",.0f"
    if metric == "train CPU s":
        return ".2f"
    return ".3f" if metric.startswith(("objective", "x_")) else ".2f"


def mean_se_text(values: Sequence[float], spec: str, *, signed: bool = False) -> str:
    from metrics import format_mean_se, mean_se

    if not values:
        return "-"
    values = [v for v in values if not math.isnan(v)]
    if not values:
        return "nan"
    mean, se = mean_se(values)
    text = format_mean_se(mean, se, spec)
    return ("+" + text if signed and not text.startswith("-") else text)


def beyond_two_se(values: Sequence[float]) -> bool | None:
    """Whether the mean of ``values`` is more than two standard errors from 0 (None when the s.e. is unknown)."""
    from metrics import mean_se

    values = [v for v in values if not math.isnan(v)]
    if len(values) < 2:
        return None
    mean, se = mean_se(values)
    return abs(mean) > 2 * se


def table(results: Sequence[SearchResult]) -> list[str]:
    """The printed table: one row per (search, model), a ``two − one`` row per search, and a verdict line each."""
    measure_names = results[0].data.measure_names
    metrics = metric_names(measure_names, "two_stage")
    shared = metric_names(measure_names, "one_stage")
    timing = ["train CPU s", "predict levels/s"]
    columns = ["search", "model", *metrics, *timing]
    rows: list[list[str]] = []
    notes: list[str] = []
    for result in results:
        for kind in KINDS:
            rows.append([result.data.name, LABELS[kind],
                         *(mean_se_text(result.values(kind, m), spec_of(m)) for m in metrics),
                         *(mean_se_text(result.values(kind, m), spec_of(m)) for m in timing)])
        cells, within, outside = [], [], []
        for metric in metrics:
            if metric not in shared:
                cells.append("")
                continue
            differences = result.differences(metric)
            flag = beyond_two_se(differences)
            cells.append(mean_se_text(differences, spec_of(metric), signed=True) + ("*" if flag else ""))
            (outside if flag else within).append(metric)
        rows.append([result.data.name, "two − one", *cells, "", ""])
        notes.append(f"{result.data.name}: beyond two s.e. (*): {', '.join(outside) or 'none'}; "
                     f"within two s.e.: {', '.join(within) or 'none'}")
    if len(results) > 1:
        cells, within, outside = [], [], []
        for metric in metrics:
            if metric not in shared:
                cells.append("")
                continue
            per_search = [float(np.nanmean(r.differences(metric))) for r in results]
            flag = beyond_two_se(per_search)
            cells.append(mean_se_text(per_search, spec_of(metric), signed=True) + ("*" if flag else ""))
            (outside if flag else within).append(metric)
        rows.append([f"{len(results)} searches", "two − one", *cells, "", ""])
        notes.append(f"across the {len(results)} searches (mean of each search's mean difference, s.e. over "
                     f"searches): beyond two s.e. (*): {', '.join(outside) or 'none'}; within two s.e.: "
                     f"{', '.join(within) or 'none'}")
    widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(columns, widths)))]
    previous = None
    for row in rows:
        if previous is not None and row[0] != previous:
            lines.append("")
        previous = row[0]
        lines.append("  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))))
    return lines + [""] + notes


def describe(result: SearchResult, seed: int) -> str:
    data, config = result.data, result.data.surrogate_config
    space = getattr(getattr(data.domain, "space", None), "env_id", data.domain.name)
    return (f"{data.name}: {len(data.objective)} levels of {space}, {data.levels.shape[1]} parameters, measures "
            f"{', '.join(data.measure_names)}, occupancy {data.occupancy.shape[1]}x{data.occupancy.shape[2]}; "
            f"{len(result.per_split['two_stage'])} splits (seed {seed}), {result.train_size} train / "
            f"{result.test_size} test levels; surrogate {config.epochs} epochs, batch {config.batch_size}, "
            f"lr {config.lr:g}, width {config.channels}, occupancy weight {config.occupancy_weight:g}")


def main(argv: list[str] | None = None) -> list[SearchResult]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+",
                        help="search folders (checkpoint.dsage, config.json), or parents of */search folders")
    parser.add_argument("--splits", type=int, default=3, help="random train/test splits per search (default 3)")
    parser.add_argument("--test-share", type=float, default=0.2, help="share of a search's levels tested on")
    parser.add_argument("--seed", type=int, default=0, help="seeds the splits; split k trains both models from "
                                                            "seed + k")
    parser.add_argument("--predict-levels", type=int, default=4096,
                        help="random levels per timed prediction (0: no prediction timing)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="change a surrogate setting of every search (e.g. epochs=200, lr=0.003; "
                             "the surrogate. prefix may be left out); kind cannot be set")
    args = parser.parse_args(argv)
    overrides = {}
    for text in args.set:
        from dsage_ray.config import ConfigError, parse_override

        try:
            key, value = parse_override(text)
        except ConfigError as exc:
            parser.error(str(exc))
        key = key if key.startswith("surrogate.") else f"surrogate.{key}"
        if key == "surrogate.kind":
            parser.error("--set kind: the benchmark trains both kinds")
        overrides[key] = value
    if args.splits < 1:
        parser.error("--splits must be at least 1")
    if not 0 < args.test_share < 1:
        parser.error("--test-share must lie in (0, 1)")

    import torch

    torch.set_num_threads(1)
    try:
        folders, skipped = find_searches(args.folders)
    except BenchInputError as exc:
        raise SystemExit(f"error: {exc}") from None
    named = {folder.resolve() for folder in args.folders}
    searches: list[SearchData] = []
    for folder in folders:
        try:
            searches.append(load_search(folder, overrides))
        except BenchInputError as exc:
            if folder.resolve() in named:
                raise SystemExit(f"error: {exc}") from None
            skipped.append(str(exc))
    if not searches:
        raise SystemExit("error: no search with a surrogate dataset among " + ", ".join(map(str, args.folders)))
    names = [s.measure_names for s in searches]
    if len(set(names)) > 1:
        raise SystemExit(f"error: the searches have different measures ({sorted(set(names))}); bench them apart")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    device = build_surrogate(searches[0], "one_stage", 0).device
    changed = f"; surrogate settings changed from the runs': {', '.join(args.set)}" if args.set else ""
    print(f"{len(searches)} search(es); torch threads 1 on {device}, load average {load:.1f} on "
          f"{os.cpu_count()} CPUs; times are CPU time{changed}")
    for line in skipped:
        print(f"skipped {line}")
    results = []
    for data in searches:
        result = evaluate_search(data, count=args.splits, test_share=args.test_share, seed=args.seed,
                                 predict_count=args.predict_levels)
        print(describe(result, args.seed), flush=True)
        results.append(result)
    print()
    print(f"mean ± s.e. over splits; two − one: two-stage minus one-stage per split (paired), * beyond two s.e.; "
          f"ρ: Spearman on the test levels; predict levels/s: {args.predict_levels} random levels per call, "
          f"first split's models")
    for line in table(results):
        print(line)
    return results


if __name__ == "__main__":
    main()
