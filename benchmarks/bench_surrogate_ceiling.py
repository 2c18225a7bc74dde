"""A fair surrogate benchmark for the Maze: the surrogate against trivial predictors, on the same test levels.

Scores a Maze dataset, either a standalone .npz (``--data FILE.npz``, format in ``benchmarks/maze_dataset.py``)
or a finished Maze surrogate run folder (converted in memory the same way), on the path-length measure
``mean_path_length``. For each of ``--splits`` random splits, ``--test`` levels are set aside and, for each
training size N, the surrogate setting is trained from scratch on N of the other levels, ``--inits`` times
(weight initialisation and shuffling seeds), with a training window of at least N (the whole training set).
Every predictor is scored by its Spearman ρ with the agent's path length on the split's test levels:

* **surrogate**: the Maze ``cpu`` preset's surrogate (``--set`` / ``--setting`` change it), ``--epochs`` epochs;
* **optimal path**: the BFS shortest start-goal distance alone (no training);
* **random walk**: the expected steps of a uniform random walker from the start to the goal, its hitting time
  (no training; ``dsage_ray.surrogate.grid_features.RandomWalkFields``);
* **GBM**: scikit-learn's HistGradientBoostingRegressor on BFS features of the level (distances, dead ends,
  junctions, detours; trained on the same N levels);
* **test-retest**: the agent's second evaluation (other seeds) where the data has one (``measures_retest``).

mean ± s.e. are over the splits, each split's value being the mean over its initialisations (the splits
are the independent repeats; initialisations of one split share its test levels). Also printed: each
setting's FLOPs and predictions/s (encoding included, as in the inner loop) and the GBM's, the difference
surrogate − baseline per split, with ``--inits`` > 1 the initialisations' mean prediction alone and
rank-averaged with the GBM's and with the random walker's, and their disagreement as an uncertainty of that mean
(:class:`Disagreement`; ``--certain-share``), the held-out levels' ρ (``--holdout FILE.npz``, or
a run's own), and with an ``iteration`` column the search's own next levels: the last ``--test`` levels in
evaluation order, trained on the N levels evaluated just before them.

The last lines, one per N, are exactly (the first setting's surrogate)::

    N=<n>: surrogate ρ <x> ± <se> | optimal path ρ <y> ± <se> | GBM ρ <z> ± <se>

Usage:
    python benchmarks/bench_surrogate_ceiling.py --data FILE.npz [--sizes 200,400,800,1600] [--splits 3] [--inits 3]
    python benchmarks/bench_surrogate_ceiling.py RUN_FOLDER [--retest 300]
    python benchmarks/bench_surrogate_ceiling.py --data FILE.npz --setting cpu: \\
        --setting dist:bench.distance_fields=true

Benchmark-only keys of a setting (other keys are the run config's; ``surrogate.`` may be left out):

* ``bench.distance_fields=true`` wraps the network with ``dsage_ray.surrogate.grid_features.DistanceFields`` (BFS
  distance from the start, to the goal, and the detour, as three more input channels);
* ``bench.level_statistics=true`` builds the network with ``dsage_ray.surrogate.grid_features.LevelStatistics``: the
  GBM's BFS features, computed inside the network, fed to its measure heads. The path length then needs a head
  (``occupancy_sum_measure=``), or:
* ``bench.sum_residual=true`` keeps the occupancy-sum path length and adds its head's output to it;
* ``bench.random_walk=true`` wraps the network with ``dsage_ray.surrogate.grid_features.RandomWalkFields`` (the random
  walker's log expected visits per cell as one more input channel; after the distance fields when both are on);
* ``bench.rotations=true`` trains on every level and its three rotations by 90° (the walls, start, goal and
  occupancy turned together, the measures kept). Sound only for an agent that ``bench_symmetry.py`` finds
  invariant under them; ACCEL is not (it reads its absolute heading), and for it the turned copies did not help
  (``docs/results/surrogate_accuracy``). ``bench.rotations=tta`` also predicts each level as the mean over its
  four rotations.
* ``bench.chain=MODES`` replaces the network with ``PolicyChain`` (``benchmarks/policy_chain.py``): a learned
  stochastic controller with ``MODES`` memory modes that reads the agent's egocentric view, whose expected
  occupancy is propagated exactly over the step limit. It trains on the agent's occupancy and path length with
  the setting's ``epochs``, ``batch_size`` and ``lr`` (``lr=0.003`` in ``docs/results/surrogate_accuracy``), and
  predicts the path length only. Against the network on 1,600 levels, one thread (``docs/results/surrogate_accuracy``):
  2 modes train about 190 times as long and predict 90–180 times as slowly; 4 modes, about 500 and 280–490 times;
  8 modes (one split), about 2,400 and 1,800 times (the propagation's work grows as modes²).

With more than one setting, the first setting's predictions are also rank-averaged with each other's
(``<first> + <other> ranks``): two model families combined.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from maze_dataset import PATH_LENGTH, MazeData, MazeDatasetError  # noqa: E402

#: Benchmark-only setting keys (not run config keys).
BENCH_KEYS = ("bench.distance_fields", "bench.level_statistics", "bench.sum_residual", "bench.random_walk",
              "bench.rotations", "bench.chain")
#: Quarter turns a level is trained on with ``bench.rotations``.
QUARTER_TURNS = (0, 1, 2, 3)


# ------------------------------------------------------------------------------------------- features


def bfs_fields(walls: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start/goal pairs (the domain's furthest pair) and the BFS distances from the start and to the goal.

    Returns:
        ``pairs (n, 3)`` (start, goal flat indices, length; -1 without a pair), ``from_start`` and ``to_goal``
        ``(n, H, W)`` float64 with -1 on cells that are not reached.
    """
    from dsage_ray.domains.maze.paths import _bfs, furthest_pairs

    n, height, width = walls.shape
    pairs = furthest_pairs(walls)
    fields = np.full((2, n, height * width), -1.0)
    dist = np.full(height * width, -1, dtype=np.int64)
    queue = np.empty(height * width, dtype=np.int64)
    for m in range(n):
        if pairs[m, 0] < 0:
            continue
        flat = np.ascontiguousarray(~walls[m]).ravel()
        for which in range(2):
            dist[:] = -1
            _bfs(flat, height, width, pairs[m, which], dist, queue)
            fields[which, m] = dist
    return pairs, fields[0].reshape(n, height, width), fields[1].reshape(n, height, width)


FEATURE_NAMES = (
    "walls", "reachable", "optimal_path", "on_shortest_paths", "dead_ends", "junctions", "shortest_path_junctions",
    "mean_from_start", "max_from_start", "mean_detour", "max_detour", "detour<=2", "detour<=6", "detour<=12",
    "start_row", "start_col", "goal_row", "goal_col", "manhattan", "path/manhattan",
)


def bfs_features(walls: np.ndarray) -> np.ndarray:
    """``(n, len(FEATURE_NAMES))`` float64: hand-made BFS features of each level (what the GBM reads)."""
    n, height, width = walls.shape
    pairs, from_start, to_goal = bfs_fields(walls)
    empty = ~walls
    padded = np.pad(empty, ((0, 0), (1, 1), (1, 1)))
    degree = (padded[:, :-2, 1:-1].astype(int) + padded[:, 2:, 1:-1] + padded[:, 1:-1, :-2] + padded[:, 1:-1, 2:])
    out = np.zeros((n, len(FEATURE_NAMES)))
    for m in range(n):
        reach = from_start[m] >= 0
        length = float(max(pairs[m, 2], 0))
        detour = np.where(reach & (to_goal[m] >= 0), from_start[m] + to_goal[m] - length, np.nan)
        on_path = detour == 0
        start, goal = (divmod(int(p), width) if p >= 0 else (0, 0) for p in pairs[m, :2])
        manhattan = abs(start[0] - goal[0]) + abs(start[1] - goal[1])
        any_reach = bool(reach.any())
        out[m] = (
            walls[m].sum(), reach.sum(), length, on_path.sum(), (reach & (degree[m] == 1)).sum(),
            (reach & (degree[m] >= 3)).sum(), (on_path & (degree[m] >= 3)).sum(),
            from_start[m][reach].mean() if any_reach else 0.0, from_start[m].max(),
            np.nanmean(detour) if any_reach else 0.0, np.nanmax(detour) if any_reach else 0.0,
            (detour <= 2).sum(), (detour <= 6).sum(), (detour <= 12).sum(),
            *start, *goal, manhattan, length / max(manhattan, 1),
        )
    return out


def hitting_times(walls: np.ndarray, *, chunk: int = 250) -> np.ndarray:
    """``(n,)`` float64: the expected steps of a uniform random walker from the start to the goal of each level
    (the Maze's ``surrogate.prior_measure`` prior, :func:`dsage_ray.domains.maze.prior.walker_prior`; 0 without a
    start-goal pair). A parameter-free baseline: how hard the maze is for an agent that explores blindly."""
    import torch

    from dsage_ray.domains.maze.encoding import SPARE, encode_levels
    from dsage_ray.domains.maze.prior import walker_prior
    from dsage_ray.surrogate.models import pad_to_power_of_two

    n, height, width = walls.shape
    hitting_time = walker_prior(PATH_LENGTH)
    out = np.zeros(n)
    for first in range(0, n, chunk):
        part = walls[first:first + chunk]
        encoded = pad_to_power_of_two(encode_levels(part.reshape(len(part), -1).astype(np.int8), height, width),
                                      pad_channel=SPARE)
        out[first:first + chunk] = hitting_time(torch.from_numpy(encoded)).numpy()
    return out


# ------------------------------------------------------------------------------------------- settings


@dataclasses.dataclass
class Setting:
    """One surrogate setting: a run config's surrogate/maze sections plus benchmark-only switches."""

    name: str
    config: object  # RunConfig
    distance_fields: bool = False
    level_statistics: bool = False
    sum_residual: bool = False
    random_walk: bool = False
    rotations: str = ""  # "", "train" or "tta"
    chain: int = 0  # memory modes of a PolicyChain instead of the network; 0: the network

    @classmethod
    def parse(cls, text: str, *, epochs: int | None, extra: dict) -> "Setting":
        from bench_surrogate_training import parse_setting

        from dsage_ray.config import RunConfig

        name, overrides = parse_setting(text) if ":" in text else (text, {})
        overrides = {**extra, **overrides}
        bench = {key: overrides.pop(key) for key in list(overrides) if key in BENCH_KEYS}
        unknown = [key for key in overrides if key.startswith("bench.")]
        if unknown:
            raise SystemExit(f"--setting {text!r}: unknown benchmark key(s) {unknown} (known: {BENCH_KEYS})")
        values = {"domain": "maze", "preset": "cpu", "maze.agent": "builtin:wall_follower"}
        if epochs is not None:
            values["surrogate.epochs"] = epochs
        config = RunConfig.build({**values, **overrides})
        return cls(name=name, config=config, distance_fields=bool(bench.get("bench.distance_fields", False)),
                   level_statistics=bool(bench.get("bench.level_statistics", False)),
                   sum_residual=bool(bench.get("bench.sum_residual", False)),
                   random_walk=bool(bench.get("bench.random_walk", False)),
                   rotations=_rotations(bench.get("bench.rotations", False), text),
                   chain=_chain_modes(bench.get("bench.chain", 0), text))

    def describe(self) -> str:
        s = self.config.surrogate
        if self.chain:
            return (f"policy chain (benchmarks/policy_chain.py), {self.chain} memory mode(s), {s.epochs} epochs, "
                    f"batch {s.batch_size}, lr {s.lr:g}; predicts {PATH_LENGTH} only")
        parts = [s.kind, f"{s.epochs} epochs", f"batch {s.batch_size}", f"channels {s.channels}",
                 f"path channels {self.config.maze.path_channels}"]
        if s.occupancy_sum_measure:
            parts.append(f"{s.occupancy_sum_measure} = occupancy sum")
        if self.distance_fields:
            parts.append("distance fields")
        if self.level_statistics:
            parts.append("level statistics into the heads")
        if self.sum_residual:
            parts.append("occupancy sum + its head's output")
        if self.random_walk:
            parts.append("random-walk visits")
        if self.rotations:
            parts.append("trained on 4 rotations" + (", predicted as their mean" if self.rotations == "tta" else ""))
        if s.prior_measure:
            parts.append(f"{s.prior_measure} blended with the random walker's hitting time")
        return ", ".join(parts)


def _rotations(value, text: str) -> str:
    """``bench.rotations``: false, true (train on the 4 rotations) or ``tta`` (and predict their mean)."""
    if value in (False, "false", ""):
        return ""
    if value in (True, "true", "train"):
        return "train"
    if value == "tta":
        return "tta"
    raise SystemExit(f"--setting {text!r}: bench.rotations is true, false or tta, not {value!r}")


def _chain_modes(value, text: str) -> int:
    """``bench.chain``: the policy chain's memory modes (0 or false: the network)."""
    if value in (False, "false", "", 0):
        return 0
    if isinstance(value, int) and not isinstance(value, bool) and value >= 1:
        return value
    raise SystemExit(f"--setting {text!r}: bench.chain is a number of memory modes >= 1 (or 0), not {value!r}")


class ChainModel:
    """The policy chain of one setting for one dataset, with :class:`Model`'s interface (path length only)."""

    def __init__(self, setting: Setting, data: MazeData, *, train_size: int, seed: int) -> None:
        import torch

        from policy_chain import PolicyChain
        from dsage_ray.domains.maze.level import max_steps_for

        if data.occupancy is None:
            raise SystemExit(f"setting {setting.name}: bench.chain trains on the agent's occupancy, which this data "
                             "does not hold")
        self.setting, self.data, self.seed = setting, data, seed
        # Weights drawn inside a forked RNG, as the surrogate's are: the global RNG stays untouched.
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.chain = PolicyChain(max_steps=max_steps_for(*data.shape), modes=setting.chain)

    def encode(self, walls: np.ndarray) -> np.ndarray:
        return np.asarray(walls, dtype=bool)  # the chain builds its inputs per batch: they are large

    def train(self, rows: np.ndarray, encoded: np.ndarray) -> float:
        from policy_chain import train_chain

        s = self.setting.config.surrogate
        start = time.perf_counter()
        train_chain(self.chain, encoded[rows], self.data.occupancy[rows],
                    self.data.measures[rows, self.data.measure(PATH_LENGTH)], epochs=s.epochs,
                    batch_size=s.batch_size, lr=s.lr, seed=self.seed)
        return time.perf_counter() - start

    def predict(self, encoded: np.ndarray, column: int) -> np.ndarray:
        if column != self.data.measure(PATH_LENGTH):
            raise ValueError(f"the policy chain predicts {PATH_LENGTH} only, not {self.data.measure_names[column]}")
        return self.predict_batch(encoded)

    def predict_batch(self, encoded: np.ndarray) -> np.ndarray:
        from policy_chain import predict_path_length

        return predict_path_length(self.chain, encoded)

    def flops(self, sample: np.ndarray) -> float:
        from policy_chain import flops_per_level

        return flops_per_level(self.chain, *self.data.shape)


def make_model(setting: Setting, data: MazeData, *, train_size: int, seed: int):
    """The setting's predictor: the policy chain with ``bench.chain``, else the surrogate network."""
    kind = ChainModel if setting.chain else Model
    return kind(setting, data, train_size=train_size, seed=seed)


class Model:
    """A surrogate of one setting for one dataset: encodes levels as the domain does, trains, predicts."""

    def __init__(self, setting: Setting, data: MazeData, *, train_size: int, seed: int) -> None:
        from dsage_ray.domains.maze.encoding import EMPTY, GOAL, SPARE, START
        from dsage_ray.surrogate import Surrogate
        from dsage_ray.domains.maze.prior import walker_prior
        from dsage_ray.surrogate.grid_features import DistanceFields, LevelStatistics, RandomWalkFields
        from dsage_ray.surrogate.models import WithInputFields

        self.setting = setting
        self.data = data
        height, width = data.shape
        surrogate_config = setting.config.surrogate
        kind, sum_measure = surrogate_config.kind, surrogate_config.occupancy_sum_measure
        if data.occupancy is None and kind == "two_stage":
            kind, sum_measure = "one_stage", ""  # announced once by the caller
        if sum_measure and sum_measure not in data.measure_names:
            sum_measure = ""
        copies = len(QUARTER_TURNS) if setting.rotations else 1
        config = dataclasses.replace(surrogate_config, device="cpu", precision="fp32",
                                     train_window=max(surrogate_config.train_window, copies * train_size),
                                     occupancy_sum_measure=sum_measure)
        sample = self.encode(data.walls[:1])
        channels = sample.shape[1]
        if setting.rotations and not (height == width and sample.shape[2:] == (height, width)):
            raise SystemExit(f"bench.rotations needs square levels that the encoding does not pad; these are "
                             f"{height}x{width}, encoded as {sample.shape[2]}x{sample.shape[3]}")
        fields = DistanceFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL,
                                norm=height * width / 2)
        statistics = LevelStatistics(fields=fields, norm=height * width / 2) if setting.level_statistics else None
        inputs = [fields] if setting.distance_fields else []
        if setting.random_walk:
            inputs.append(RandomWalkFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL,
                                           norm=math.log1p(height * width)))
        extra = sum(module.fields for module in inputs)
        self.surrogate = Surrogate(kind=kind, input_channels=channels + extra, input_shape=tuple(sample.shape[2:]),
                                   occupancy_shape=(height, width), num_measures=len(data.measure_names),
                                   config=config, seed=seed, measure_names=data.measure_names,
                                   statistics=statistics, sum_residual=setting.sum_residual,
                                   prior=walker_prior(config.prior_measure) if config.prior_measure else None)
        self.input_channels = channels
        if inputs:
            import torch

            self.surrogate.model = WithInputFields(inputs, self.surrogate.model)
            self.surrogate.input_channels = channels  # what predict() and the dataset see: the one-hot level
            self.surrogate.optimizer = torch.optim.Adam(self.surrogate.model.parameters(), lr=config.lr)
        self.pad_channel = SPARE

    def encode(self, walls: np.ndarray) -> np.ndarray:
        from dsage_ray.domains.maze.encoding import SPARE, encode_levels
        from dsage_ray.surrogate.models import pad_to_power_of_two

        n, height, width = walls.shape
        encoded = encode_levels(walls.reshape(n, -1).astype(np.int8), height, width,
                                path_channels=self.setting.config.maze.path_channels)
        return pad_to_power_of_two(encoded, pad_channel=SPARE)

    def train(self, rows: np.ndarray, encoded: np.ndarray) -> float:
        from dsage_ray.types import EvaluationResult

        data = self.data
        height, width = data.shape
        occupancy = data.occupancy if data.occupancy is not None else np.zeros((len(data), height, width), np.float32)
        dataset = self.surrogate.make_dataset()
        for turns in QUARTER_TURNS if self.setting.rotations else (0,):
            # A square level's encoding is unpadded (16 x 16), so turning it turns walls, start and goal together.
            dataset.append(encoded=np.rot90(encoded[rows], turns, axes=(2, 3)).copy(), results=[
                EvaluationResult(objective=1.0, measures=data.measures[i].astype(np.float64),
                                 occupancy=np.rot90(occupancy[i], turns).copy())
                for i in rows])
        start = time.perf_counter()
        self.surrogate.train(dataset)
        return time.perf_counter() - start

    def predict(self, encoded: np.ndarray, column: int) -> np.ndarray:
        if self.setting.rotations == "tta":
            return np.mean([self.surrogate.predict(np.rot90(encoded, turns, axes=(2, 3)).copy()).measures[:, column]
                            for turns in QUARTER_TURNS], axis=0)
        return self.surrogate.predict(encoded).measures[:, column]

    def predict_batch(self, encoded: np.ndarray) -> np.ndarray:
        return self.surrogate.predict(encoded).measures

    def flops(self, sample: np.ndarray) -> float:
        return flops_per_prediction(self, sample)


# ------------------------------------------------------------------------------------------- scoring


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    from scipy import stats

    if np.ptp(a) == 0 or np.ptp(b) == 0:
        return 0.0  # a constant prediction ranks nothing
    return float(stats.spearmanr(a, b).statistic)


@dataclasses.dataclass(frozen=True)
class Disagreement:
    """How well the initialisations' spread points at the error of their mean prediction, on one split.

    Attributes:
        spread_rho: Spearman ρ of the spread (std over the initialisations) with the mean's absolute error.
        value_rho: Spearman ρ of the mean prediction itself with that error: the part of the spread's ρ that
            only says "long paths are harder" (the paper's Fig. 8 finding).
        within_rho: The spread's ρ with the error among levels of similar prediction: the mean over 10 equal bins
            of the prediction (its deciles; fewer bins when there are under 200 levels, so that each holds at least
            20). What a selection that picks among a block's elites (whose predictions are alike) could use.
        mae: The mean's MAE on every test level.
        certain_mae: Its MAE on the ``fraction`` of test levels with the least spread.
    """

    spread_rho: float
    value_rho: float
    within_rho: float
    mae: float
    certain_mae: float

    @classmethod
    def of(cls, predictions: np.ndarray, truth: np.ndarray, *, fraction: float) -> "Disagreement":
        mean, spread = predictions.mean(axis=0), predictions.std(axis=0)
        error = np.abs(mean - truth)
        certain = np.argsort(spread, kind="stable")[:max(1, int(round(fraction * len(truth))))]
        bins = np.array_split(np.argsort(mean, kind="stable"), int(np.clip(len(truth) // 20, 1, 10)))
        within = [spearman(spread[b], error[b]) for b in bins]
        return cls(spread_rho=spearman(spread, error), value_rho=spearman(mean, error),
                   within_rho=float(np.mean(within)), mae=float(error.mean()),
                   certain_mae=float(error[certain].mean()))


def make_gbm(seed: int):
    try:
        from sklearn.ensemble import HistGradientBoostingRegressor
    except ImportError:
        raise SystemExit("the GBM baseline needs scikit-learn: pip install 'dsage_ray[bench]' "
                         "(or pip install scikit-learn)") from None
    return HistGradientBoostingRegressor(max_iter=300, learning_rate=0.05, random_state=seed)


def flops_per_prediction(model, sample) -> float:
    import torch
    from bench_surrogate import flops_per_sample

    return flops_per_sample(model.surrogate.model, torch.from_numpy(sample))


def throughput(fn, batch: int, repeats: int = 5) -> float:
    """Calls per second × batch: the best of ``repeats`` timed calls after a warm-up."""
    from bench_surrogate import best_time

    return batch / best_time(fn, calls=repeats)


def summary(per_split, spec: str = ".3f") -> str:
    from metrics import format_mean_se, mean_se

    return format_mean_se(*mean_se(per_split), spec)


def load_data(args) -> tuple[MazeData, MazeData | None, str]:
    import maze_dataset

    if (args.run is None) == (args.data is None):
        raise SystemExit("give a run folder or --data FILE.npz (one of them)")
    try:
        if args.data is not None:
            data = maze_dataset.load(args.data)
            held = maze_dataset.load(args.holdout) if args.holdout is not None else None
            return data, held, str(args.data)
        data, held = maze_dataset.from_run(args.run, retest=args.retest, seed=args.seed)
        if args.holdout is not None:
            held = maze_dataset.load(args.holdout)
        return data, held, str(args.run)
    except MazeDatasetError as exc:
        raise SystemExit(f"error: {exc}") from None


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, nargs="?", help="a finished Maze surrogate run folder")
    parser.add_argument("--data", type=Path, help="a Maze dataset .npz (benchmarks/maze_dataset.py)")
    parser.add_argument("--holdout", type=Path, help="another .npz scored too (default with a run: its held-out)")
    parser.add_argument("--retest", type=int, default=0, help="with a run: re-evaluate this many of its levels")
    parser.add_argument("--sizes", default="200,400,800,1600", help="training sizes N (those that fit are used)")
    parser.add_argument("--test", type=int, default=400, help="test levels per split")
    parser.add_argument("--splits", type=int, default=3)
    parser.add_argument("--inits", type=int, default=3)
    parser.add_argument("--epochs", type=int, default=30, help="training epochs (a setting's epochs= wins)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="a run config key for every setting, on the Maze cpu preset")
    parser.add_argument("--setting", action="append", default=[],
                        help="NAME:key=value,... (repeatable; the first is the one of the last lines)")
    parser.add_argument("--no-future", action="store_true", help="skip the search's-next-levels test")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (a Maze run trains on 1)")
    parser.add_argument("--batch", type=int, default=150, help="batch of the predictions/s figures (inner loop)")
    parser.add_argument("--certain-share", type=float, default=0.5,
                        help="with --inits > 1: the share of test levels the ensemble is surest of, scored apart")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not 0 < args.certain_share <= 1:
        parser.error(f"--certain-share must be in (0, 1], got {args.certain_share}")

    import torch
    from scipy import stats

    from dsage_ray.config import parse_override

    torch.set_num_threads(args.threads)
    data, held, source = load_data(args)
    column = data.measure(PATH_LENGTH)
    values = data.measures[:, column]
    extra = dict(parse_override(item) for item in args.overrides)
    settings = [Setting.parse(text, epochs=args.epochs, extra=extra) for text in (args.setting or ["cpu"])]
    sizes = sorted({int(n) for n in args.sizes.split(",")})
    pool_size = len(data) - args.test
    fitting = [n for n in sizes if n <= pool_size]
    if pool_size < 1 or not fitting:
        raise SystemExit(f"{source}: {len(data)} levels cannot hold {args.test} test levels and N = {sizes[0]} "
                         f"training levels (lower --test or --sizes)")
    if fitting != sizes:
        print(f"note: N = {[n for n in sizes if n not in fitting]} left out: {len(data)} levels minus {args.test} "
              "test levels is fewer")
    sizes = fitting

    print(f"data {source}: {len(data)} levels, measure {PATH_LENGTH}; {args.splits} splits x {args.inits} "
          f"initialisations, {args.test} test levels per split; torch threads {args.threads}, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    if data.occupancy is None:
        print("note: the data has no occupancy: two-stage settings train as one_stage")
    for setting in settings:
        print(f"setting {setting.name}: {setting.describe()}; training window >= N")

    features = bfs_features(data.walls)
    optimal = features[:, FEATURE_NAMES.index("optimal_path")]
    walker = hitting_times(data.walls)
    held_features = bfs_features(held.walls) if held is not None else None
    encoded = {s.name: make_model(s, data, train_size=1, seed=0).encode(data.walls) for s in settings}
    held_encoded = ({s.name: make_model(s, data, train_size=1, seed=0).encode(held.walls) for s in settings}
                    if held is not None else {})
    held_values = held.measures[:, held.measure(PATH_LENGTH)] if held is not None else None

    # Costs per setting (and of the GBM), timed on the inner loop's batch, encoding included.
    batch_walls = data.walls[np.arange(args.batch) % len(data)]
    cost: dict[str, tuple[float, float, float]] = {}
    for setting in settings:
        model = make_model(setting, data, train_size=1, seed=0)
        # Trained once on a few levels, so that what a trained surrogate adds to a prediction (a prior's
        # blend) is timed too.
        model.train(np.arange(min(len(data), 32)), encoded[setting.name])
        sample = model.encode(batch_walls)
        flops = model.flops(sample)
        repeats = 2 if setting.chain else 5
        model_rate = throughput(lambda: model.predict_batch(sample), args.batch, repeats=repeats)
        full_rate = throughput(lambda: model.predict_batch(model.encode(batch_walls)), args.batch, repeats=repeats)
        cost[setting.name] = (flops, model_rate, full_rate)

    # rho[name][n] = per-split means; the baselines keyed alike.
    rho: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    mae: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    held_rho: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    train_s: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    # The inits' mean prediction (an ensemble of --inits models), alone and rank-averaged with the GBM.
    ensemble_rho: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    with_gbm_rho: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    with_walker_rho: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings}
    # The inits' disagreement as an uncertainty: does it point at the mean's errors?
    disagreement: dict[str, dict[int, list[Disagreement]]] = {s.name: {n: [] for n in sizes} for s in settings}
    pair_rho: dict[str, dict[int, list[float]]] = {s.name: {n: [] for n in sizes} for s in settings[1:]}
    primary = settings[0].name
    gbm_rho: dict[int, list[float]] = {n: [] for n in sizes}
    gbm_held: dict[int, list[float]] = {n: [] for n in sizes}
    optimal_rho: list[float] = []
    walker_rho: list[float] = []
    retest_rho: list[tuple[float, int]] = []
    gbm_rate = 0.0
    for split in range(args.splits):
        order = np.random.default_rng([args.seed, split]).permutation(len(data))
        test, pool = order[:args.test], order[args.test:]
        optimal_rho.append(spearman(optimal[test], values[test]))
        walker_rho.append(spearman(walker[test], values[test]))
        if data.retest is not None:
            twice = test[np.isfinite(data.retest[test, column])]
            if len(twice) >= 3:
                retest_rho.append((spearman(data.retest[twice, column], values[twice]), len(twice)))
        for n in sizes:
            train = np.sort(pool[:n])
            gbm = make_gbm(args.seed).fit(features[train], values[train])
            gbm_test = gbm.predict(features[test])
            gbm_rho[n].append(spearman(gbm_test, values[test]))
            if held is not None:
                gbm_held[n].append(spearman(gbm.predict(held_features), held_values))
            if not gbm_rate:
                gbm_rate = throughput(lambda: gbm.predict(bfs_features(batch_walls)), args.batch, repeats=3)
            split_ensembles: dict[str, np.ndarray] = {}
            for setting in settings:
                per_init, per_init_mae, per_init_held, seconds, predictions = [], [], [], [], []
                for init in range(args.inits):
                    model = make_model(setting, data, train_size=n, seed=1000 * split + init)
                    seconds.append(model.train(train, encoded[setting.name]))
                    predicted = model.predict(encoded[setting.name][test], column)
                    predictions.append(predicted)
                    per_init.append(spearman(predicted, values[test]))
                    per_init_mae.append(float(np.abs(predicted - values[test]).mean()))
                    if held is not None:
                        per_init_held.append(spearman(model.predict(held_encoded[setting.name], column), held_values))
                rho[setting.name][n].append(float(np.mean(per_init)))
                ensemble = np.mean(predictions, axis=0)
                ensemble_rho[setting.name][n].append(spearman(ensemble, values[test]))
                if args.inits > 1:
                    disagreement[setting.name][n].append(
                        Disagreement.of(np.asarray(predictions), values[test], fraction=args.certain_share))
                for blend, other in ((with_gbm_rho, gbm_test), (with_walker_rho, walker[test])):
                    blend[setting.name][n].append(spearman(stats.rankdata(ensemble) + stats.rankdata(other),
                                                           values[test]))
                mae[setting.name][n].append(float(np.mean(per_init_mae)))
                train_s[setting.name][n].append(float(np.mean(seconds)))
                if held is not None:
                    held_rho[setting.name][n].append(float(np.mean(per_init_held)))
                print(f"  split {split} N={n:>5} {setting.name}: surrogate ρ {np.mean(per_init):.3f} "
                      f"(inits {', '.join(f'{r:.3f}' for r in per_init)}), MAE {np.mean(per_init_mae):.1f}, "
                      f"train {np.mean(seconds):.1f} s | optimal path ρ {optimal_rho[-1]:.3f} | "
                      f"random walk ρ {walker_rho[-1]:.3f} | GBM ρ {gbm_rho[n][-1]:.3f}", flush=True)
                split_ensembles[setting.name] = ensemble
            # The first setting's predictions rank-averaged with each other setting's (two model families).
            for setting in settings[1:]:
                pair_rho[setting.name][n].append(spearman(
                    stats.rankdata(split_ensembles[primary]) + stats.rankdata(split_ensembles[setting.name]),
                    values[test]))

    # The search's own next levels: the last --test levels in evaluation order, trained on the N before them.
    future: dict[str, dict[int, list[float]]] = {s.name: {} for s in settings}
    if data.iteration is not None and not args.no_future and len(np.unique(data.iteration)) > 1:
        test = np.arange(len(data) - args.test, len(data))
        print(f"search's next levels: the last {args.test} levels evaluated (iterations "
              f"{int(data.iteration[test].min())}-{int(data.iteration[test].max())}), each N trained on the N before "
              f"them; ρ mean ± s.e. over {args.inits} initialisations")
        for n in sizes:
            train = np.arange(len(data) - args.test - n, len(data) - args.test)
            gbm = make_gbm(args.seed).fit(features[train], values[train])
            parts = [f"optimal path ρ {spearman(optimal[test], values[test]):.3f}",
                     f"GBM ρ {spearman(gbm.predict(features[test]), values[test]):.3f}"]
            for setting in settings:
                per_init = []
                for init in range(args.inits):
                    model = make_model(setting, data, train_size=n, seed=7919 + init)
                    model.train(train, encoded[setting.name])
                    per_init.append(spearman(model.predict(encoded[setting.name][test], column), values[test]))
                future[setting.name][n] = per_init
                parts.insert(0, f"{setting.name} ρ {summary(per_init)}")
            print(f"  N={n:>5}: " + " | ".join(parts), flush=True)

    print(f"\ncosts (torch threads {args.threads}, batch {args.batch}, best of 5): "
          + "; ".join(f"{name} {flops / 1e6:.1f} MFLOP/prediction, {full:,.0f} predictions/s with encoding "
                      f"({model_rate:,.0f}/s model only)" for name, (flops, model_rate, full) in cost.items())
          + f"; GBM {gbm_rate:,.0f} predictions/s with its BFS features")
    print(f"Spearman ρ with the agent's {PATH_LENGTH} on the test levels, mean ± s.e. over {args.splits} splits "
          f"(each the mean of {args.inits} initialisations):")
    print(f"  optimal path length alone: ρ {summary(optimal_rho)}")
    print(f"  random walker's hitting time alone: ρ {summary(walker_rho)}")
    if retest_rho:
        print(f"  the agent against itself (measures_retest): ρ {summary([r for r, _ in retest_rho])} "
              f"({', '.join(str(k) for _, k in retest_rho)} test levels evaluated twice)")
    else:
        print("  the agent against itself: not in this data (no measures_retest; `maze_dataset.py from-run "
              "--retest K` or `build --retest-share` add one)")
    header = ["setting", "N", "test ρ", "Δρ vs optimal path", "Δρ vs GBM", "test MAE", "train s"]
    if held is not None:
        header.append(f"held-out ρ ({len(held)} levels)")
    rows = []
    for setting in settings:
        for n in sizes:
            r = rho[setting.name][n]
            row = [setting.name, str(n), summary(r), summary(np.subtract(r, optimal_rho)),
                   summary(np.subtract(r, gbm_rho[n])), summary(mae[setting.name][n], ".1f"),
                   f"{np.mean(train_s[setting.name][n]):.1f}"]
            if held is not None:
                row.append(summary(held_rho[setting.name][n]))
            rows.append(row)
            if args.inits > 1:
                for label, combined in ((f"mean of {args.inits}", ensemble_rho),
                                        (f"mean of {args.inits} + GBM ranks", with_gbm_rho),
                                        (f"mean of {args.inits} + random-walk ranks", with_walker_rho)):
                    r = combined[setting.name][n]
                    rows.append([f"{setting.name}, {label}", str(n), summary(r), summary(np.subtract(r, optimal_rho)),
                                 summary(np.subtract(r, gbm_rho[n])), "", ""] + ([""] if held is not None else []))
    for setting in settings[1:]:
        for n in sizes:
            r = pair_rho[setting.name][n]
            rows.append([f"{primary} + {setting.name} ranks", str(n), summary(r), summary(np.subtract(r, optimal_rho)),
                         summary(np.subtract(r, gbm_rho[n])), "", ""] + ([""] if held is not None else []))
    for n in sizes:
        row = ["GBM", str(n), summary(gbm_rho[n]), summary(np.subtract(gbm_rho[n], optimal_rho)), "", "", ""]
        if held is not None:
            row.append(summary(gbm_held[n]))
        rows.append(row)
    rows.append(["random walk", "", summary(walker_rho), summary(np.subtract(walker_rho, optimal_rho)), "", "", ""]
                + ([f"{spearman(hitting_times(held.walls), held_values):.3f}"] if held is not None else []))
    if held is not None:
        rows.append(["optimal path", "", summary(optimal_rho), "", "", "", "",
                     f"{spearman(held_features[:, FEATURE_NAMES.index('optimal_path')], held_values):.3f}"])
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  " + " | ".join(cell.ljust(width) for cell, width in zip(row, widths)))

    if args.inits > 1:
        print(f"the {args.inits} initialisations' disagreement (std of their predictions) as the uncertainty of their "
              f"mean, mean ± s.e. over {args.splits} splits:")
        for setting in settings:
            for n in sizes:
                parts = disagreement[setting.name][n]
                print(f"  {setting.name} N={n}: ρ(spread, |error|) "
                      f"{summary([d.spread_rho for d in parts])} (ρ(prediction, |error|) "
                      f"{summary([d.value_rho for d in parts])}; within the prediction's deciles "
                      f"{summary([d.within_rho for d in parts])}) | MAE {summary([d.mae for d in parts], '.1f')}, "
                      f"on the {args.certain_share:.0%} surest {summary([d.certain_mae for d in parts], '.1f')}")
    for n in sizes:
        print(f"N={n}: surrogate ρ {summary(rho[primary][n])} | optimal path ρ {summary(optimal_rho)} | "
              f"GBM ρ {summary(gbm_rho[n])}")
    return {"rho": rho, "optimal": optimal_rho, "gbm": gbm_rho, "cost": cost, "future": future, "pairs": pair_rho,
            "ensemble": ensemble_rho, "disagreement": disagreement, "with_gbm": with_gbm_rho, "walker": walker_rho,
            "with_walker": with_walker_rho}


if __name__ == "__main__":
    main()
