"""Standalone Maze datasets (.npz) for the surrogate benchmark: the format, its checks, and two ways to make one.

The format (``numpy.savez``; every array loads with ``allow_pickle=False``):

============== ====================== ====================================================================
key            dtype / shape          meaning
============== ====================== ====================================================================
walls          uint8, N × ⌈H·W/8⌉     ``numpy.packbits`` of each level's row-major H×W interior, 1 = wall.
                                      Start and goal are not stored: they are the furthest connected pair,
                                      as in the Maze domain (``dsage_ray.domains.maze.paths.furthest_pairs``).
measures       float32, N × M         what the agent did on each level.
measure_names  str, M                 one name per column; the path length is ``mean_path_length``.
occupancy      float, N × H × W       optional: the agent's expected visits per cell (the two-stage
                                      surrogate's ancillary target).
level_shape    int, 2                 optional: ``[H, W]``; default the occupancy's, else 16 × 16.
measures_retest float32, N × M        optional: the same agent evaluated again with other seeds (NaN rows
                                      where a level was evaluated once): the agent's test-retest.
iteration      int, N                 optional: when each level was evaluated (outer iteration of a run,
                                      or 0): a later iteration is a held-out set of the search's own
                                      distribution.
============== ====================== ====================================================================

Commands::

    python benchmarks/maze_dataset.py from-run RUN_DIR [RUN_DIR ...] --out FILE.npz [--holdout-out HELD.npz] [--retest 300]
    python benchmarks/maze_dataset.py build --levels 10000 --elites RUN_DIR --out tb_logs/accel_10k.npz
    python benchmarks/maze_dataset.py check FILE.npz

``from-run`` converts a finished Maze surrogate run (its ``checkpoint.dsage`` holds every level it evaluated,
in order, and its held-out levels); several runs of one agent are concatenated in the order given (their
``iteration`` column is then dropped: the runs' iterations do not form one order; a warm-started run's
prior samples are skipped, they are another run's levels). ``build`` evaluates an agent (default ``dcd:accel``, 50 episodes) on
mutants of a run's archive elites and on random valid levels, through the Ray simulator pool
(``--workers N``) or in this process (``--workers 0``), with a progress bar; it saves every
``--save-every`` levels and ``--resume`` continues a partial file. Keep such files outside git (tb_logs/).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
from pathlib import Path
from typing import Any, Mapping

import numpy as np

#: The measure the benchmark ranks by.
PATH_LENGTH = "mean_path_length"
#: Level shape assumed when a file gives neither ``level_shape`` nor ``occupancy``.
DEFAULT_SHAPE = (16, 16)
REQUIRED = ("walls", "measures", "measure_names")
OPTIONAL = ("occupancy", "level_shape", "measures_retest", "iteration")


class MazeDatasetError(ValueError):
    """A file that does not follow the format; the message names the file and the problem."""


@dataclasses.dataclass
class MazeData:
    """A loaded, checked dataset.

    Attributes:
        walls: ``(N, H, W)`` bool, True on walls.
        measures: ``(N, M)`` float32.
        measure_names: ``M`` names.
        occupancy: ``(N, H, W)`` float32, or None.
        retest: ``(N, M)`` float32 with NaN rows for levels evaluated once, or None.
        iteration: ``(N,)`` int64, or None.
    """

    walls: np.ndarray
    measures: np.ndarray
    measure_names: tuple[str, ...]
    occupancy: np.ndarray | None = None
    retest: np.ndarray | None = None
    iteration: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.walls)

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.walls.shape[1]), int(self.walls.shape[2])

    def measure(self, name: str = PATH_LENGTH) -> int:
        """Column of measure ``name``; a clear error when the data lacks it."""
        if name not in self.measure_names:
            raise MazeDatasetError(f"measure_names {list(self.measure_names)} has no {name!r}")
        return self.measure_names.index(name)

    def solutions(self) -> np.ndarray:
        """``(N, H·W)`` int8 0/1 bitmaps: the Maze domain's solutions."""
        return self.walls.reshape(len(self), -1).astype(np.int8)

    def subset(self, rows: np.ndarray) -> "MazeData":
        pick = lambda a: None if a is None else a[rows]  # noqa: E731
        return MazeData(self.walls[rows], self.measures[rows], self.measure_names, pick(self.occupancy),
                        pick(self.retest), pick(self.iteration))

    def arrays(self) -> dict[str, np.ndarray]:
        """The file's arrays (what :func:`save` writes)."""
        height, width = self.shape
        out = {
            "walls": np.packbits(self.walls.reshape(len(self), -1).astype(bool), axis=1),
            "measures": np.asarray(self.measures, dtype=np.float32),
            "measure_names": np.array(self.measure_names, dtype=str),
            "level_shape": np.array([height, width], dtype=np.int64),
        }
        if self.occupancy is not None:
            out["occupancy"] = np.asarray(self.occupancy, dtype=np.float32)
        if self.retest is not None:
            out["measures_retest"] = np.asarray(self.retest, dtype=np.float32)
        if self.iteration is not None:
            out["iteration"] = np.asarray(self.iteration, dtype=np.int64)
        return out


def validate(arrays: Mapping[str, np.ndarray], source: str = "<arrays>") -> MazeData:
    """Checks the arrays of a dataset file and returns them as :class:`MazeData`.

    Raises:
        MazeDatasetError: naming ``source`` and the first problem found: a missing key, a wrong dtype or
            shape, a count that differs from the number of levels, missing or non-finite values.
    """
    def fail(problem: str) -> MazeDatasetError:
        return MazeDatasetError(f"{source}: {problem}")

    missing = [key for key in REQUIRED if key not in arrays]
    if missing:
        raise fail(f"missing key{'s' * (len(missing) > 1)} {', '.join(map(repr, missing))} "
                   f"(a Maze dataset holds {', '.join(REQUIRED)}; optional: {', '.join(OPTIONAL)})")
    walls, measures, names = (np.asarray(arrays[key]) for key in REQUIRED)
    if walls.dtype != np.uint8 or walls.ndim != 2:
        raise fail(f"'walls' must be uint8 of shape (N, ceil(H*W/8)) (numpy.packbits of each level), "
                   f"got {walls.dtype} of shape {walls.shape}")
    n = len(walls)
    if n == 0:
        raise fail("'walls' holds no levels")
    if measures.dtype != np.float32 or measures.ndim != 2:
        raise fail(f"'measures' must be float32 of shape (N, M), got {measures.dtype} of shape {measures.shape}")
    if len(measures) != n:
        raise fail(f"'measures' has {len(measures)} rows but 'walls' has {n} levels")
    if not np.isfinite(measures).all():
        raise fail(f"'measures' holds {int((~np.isfinite(measures)).sum())} NaN or infinite values")
    if names.dtype.kind not in "US" or names.ndim != 1:
        raise fail(f"'measure_names' must be a 1-D array of strings, got {names.dtype} of shape {names.shape}")
    names_tuple = tuple(str(name.decode() if isinstance(name, bytes) else name) for name in names)
    if len(names_tuple) != measures.shape[1]:
        raise fail(f"'measure_names' has {len(names_tuple)} names but 'measures' has {measures.shape[1]} columns")
    if PATH_LENGTH not in names_tuple:
        raise fail(f"'measure_names' {list(names_tuple)} must name the path length {PATH_LENGTH!r}")

    occupancy = arrays.get("occupancy")
    if "level_shape" in arrays:
        shape_array = np.asarray(arrays["level_shape"])
        if shape_array.dtype.kind not in "iu" or shape_array.shape != (2,) or (shape_array < 2).any():
            raise fail(f"'level_shape' must be two integers [H, W] >= 2, got {shape_array.dtype} {shape_array.tolist()}")
        shape = (int(shape_array[0]), int(shape_array[1]))
    elif occupancy is not None and np.ndim(occupancy) == 3:
        shape = tuple(np.shape(occupancy)[1:])
    else:
        shape = DEFAULT_SHAPE
    cells = shape[0] * shape[1]
    if walls.shape[1] != math.ceil(cells / 8):
        raise fail(f"'walls' has {walls.shape[1]} bytes per level; a {shape[0]}x{shape[1]} level packs into "
                   f"{math.ceil(cells / 8)} (give 'level_shape' for other sizes)")
    bits = np.unpackbits(walls, axis=1, count=cells).reshape(n, *shape).astype(bool)

    if occupancy is not None:
        occupancy = np.asarray(occupancy)
        if occupancy.dtype.kind != "f" or occupancy.shape != (n, *shape):
            raise fail(f"'occupancy' must be float of shape (N, H, W) = {(n, *shape)}, "
                       f"got {occupancy.dtype} of shape {occupancy.shape}")
        if not np.isfinite(occupancy).all():
            raise fail("'occupancy' holds NaN or infinite values")
        occupancy = occupancy.astype(np.float32)
    retest = arrays.get("measures_retest")
    if retest is not None:
        retest = np.asarray(retest)
        if retest.dtype != np.float32 or retest.shape != measures.shape:
            raise fail(f"'measures_retest' must be float32 of the shape of 'measures' {measures.shape}, "
                       f"got {retest.dtype} of shape {retest.shape}")
    iteration = arrays.get("iteration")
    if iteration is not None:
        iteration = np.asarray(iteration)
        if iteration.dtype.kind not in "iu" or iteration.shape != (n,):
            raise fail(f"'iteration' must be integers of shape ({n},), got {iteration.dtype} of shape {iteration.shape}")
        iteration = iteration.astype(np.int64)
    return MazeData(walls=bits, measures=measures.astype(np.float32), measure_names=names_tuple,
                    occupancy=occupancy, retest=retest, iteration=iteration)


def load(path: str | Path) -> MazeData:
    """Reads and checks a dataset file (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise MazeDatasetError(f"{path}: no such file")
    try:
        with np.load(path, allow_pickle=False) as file:
            arrays = {key: file[key] for key in file.files}
    except (ValueError, OSError, EOFError) as exc:  # not a zip, a damaged one, or object arrays
        raise MazeDatasetError(f"{path}: not a readable .npz of plain arrays ({exc})") from None
    return validate(arrays, str(path))


def save(data: MazeData, path: str | Path) -> Path:
    """Writes ``data`` atomically (a partial file never replaces a complete one); data that breaks the format
    (e.g. a run without the agent's path length) is refused before anything is written."""
    path = Path(path)
    arrays = data.arrays()
    validate(arrays, str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial.npz")
    np.savez(partial, **arrays)
    os.replace(partial, path)
    return path


# ------------------------------------------------------------------------------------------- from a run


def _run_state(run: str | Path) -> tuple[dict[str, Any], Any, Any]:
    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.domains import build_domain

    path = Path(run) / CHECKPOINT_NAME
    if not path.is_file():
        raise MazeDatasetError(f"{run}: no {CHECKPOINT_NAME} (a finished --local run folder holds one)")
    state = load_checkpoint(path)
    config = RunConfig.build(state["config"])
    if config.domain != "maze":
        raise MazeDatasetError(f"{run}: a {config.domain} run, not a Maze run")
    return state, config, build_domain(config)


def _iterations(history: list[dict[str, float]], count: int) -> np.ndarray | None:
    """Outer iteration of each stored sample: each iteration stored its successful evaluations, in order."""
    stored, failed_before = [], 0.0
    for record in history:
        failed = record.get("failed_evals", 0.0)
        stored.append(int(record["evaluated_this_iteration"] - (failed - failed_before)))
        failed_before = failed
    if sum(stored) != count:
        return None
    return np.repeat(np.arange(len(stored)), stored)


def from_run(run: str | Path, *, retest: int = 0, seed: int = 0) -> tuple[MazeData, MazeData | None]:
    """The levels a finished Maze surrogate run evaluated, in evaluation order, and its held-out levels.

    Args:
        run: The run folder (holding ``checkpoint.dsage``).
        retest: Evaluate this many random levels of the run again with the run's agent (other seeds) and
            store them as ``measures_retest``; 0: none.
        seed: Chooses the retested levels and their seeds.

    Returns:
        ``(run levels, held-out levels or None)``.
    """
    from dsage_ray.domains.maze.encoding import WALL
    from dsage_ray.surrogate import SurrogateDataset

    state, config, domain = _run_state(run)
    if state.get("dataset") is None:
        raise MazeDatasetError(f"{run}: holds no surrogate dataset (a surrogate.kind = 'none' run?)")
    if PATH_LENGTH not in domain.measure_names:
        raise MazeDatasetError(f"{run}: its measures {list(domain.measure_names)} do not include the agent's path "
                               f"length {PATH_LENGTH!r} (an audit search measures the level itself); nothing written")
    stored = SurrogateDataset(level_shape=tuple(state["dataset"]["level_shape"]),
                              num_measures=len(domain.measure_names), occupancy_shape=domain.occupancy_shape)
    stored.load_state_dict(state["dataset"])
    own = slice(int(state.get("prior_samples", 0)), None)  # a warm start's prior: another run's levels
    walls = stored.levels()[own, WALL, :domain.height, :domain.width] > 0.5
    data = MazeData(walls=walls, measures=stored.measures[own].astype(np.float32), measure_names=domain.measure_names,
                    occupancy=stored.occupancy[own].astype(np.float32),
                    iteration=_iterations(state.get("history", []), len(walls)))
    if retest:
        rng = np.random.default_rng(seed)
        rows = np.sort(rng.choice(len(data), size=min(retest, len(data)), replace=False))
        data.retest = np.full_like(data.measures, np.nan)
        from tqdm import tqdm

        with Evaluator(config, workers=0) as evaluate, tqdm(total=len(rows), desc="retest", unit="level") as bar:
            data.retest[rows] = evaluate(data.solutions()[rows], seed=2_000_003 + seed, bar=bar)[0]
    held = None
    if state.get("holdout") and state["holdout"]["results"]:
        results = state["holdout"]["results"]
        solutions = np.asarray(state["holdout"]["solutions"])
        held = MazeData(walls=solutions.reshape(len(solutions), domain.height, domain.width) > 0.5,
                        measures=np.array([r.measures for r in results], dtype=np.float32),
                        measure_names=domain.measure_names,
                        occupancy=np.array([r.occupancy for r in results], dtype=np.float32))
    return data, held


def concatenate(parts: list[MazeData]) -> MazeData | None:
    """One dataset of several of the same measures, in order, each level once (its first occurrence);
    optional columns only where every part has them, and no ``iteration`` (the parts' iterations are not
    one order). None for no parts."""
    if not parts:
        return None
    names = {part.measure_names for part in parts}
    if len(names) != 1:
        raise MazeDatasetError(f"cannot concatenate datasets of different measures: {sorted(names)}")
    def joined(attribute: str) -> np.ndarray | None:
        arrays = [getattr(part, attribute) for part in parts]
        return None if any(a is None for a in arrays) else np.concatenate(arrays)
    merged = MazeData(walls=joined("walls"), measures=joined("measures"), measure_names=parts[0].measure_names,
                      occupancy=joined("occupancy"), retest=joined("retest"))
    # Two runs of one seed share their first (random) levels: a level twice would sit on both sides of a split.
    _, first = np.unique(np.packbits(merged.walls.reshape(len(merged), -1), axis=1), axis=0, return_index=True)
    return merged.subset(np.sort(first))


# ------------------------------------------------------------------------------------ an offline dataset


class Evaluator:
    """Evaluates levels through a Ray :class:`~dsage_ray.ray.pool.SimulatorPool` (``workers`` actors) or in this
    process (``workers`` 0); a context manager (closes the pool)."""

    def __init__(self, config, workers: int) -> None:
        self.config = config
        if workers > 0:
            from dsage_ray.ray.pool import SimulatorPool

            self.evaluator = SimulatorPool(config=config, num_workers=workers, cpus_per_worker=1.0)
        else:
            from dsage_ray.core.evaluation import InProcessEvaluator
            from dsage_ray.domains import build_domain

            # The run's torch threads (one): torch's default of one per core slows an agent's small batches
            # several-fold when other processes share the cores.
            self.evaluator = InProcessEvaluator(domain=build_domain(config), threads=config.torch_threads)

    def __enter__(self) -> "Evaluator":
        return self

    def __exit__(self, *exc_info) -> None:
        close = getattr(self.evaluator, "close", None)  # the Ray pool's; in-process evaluation holds nothing
        if close is not None:
            close()

    def __call__(self, solutions: np.ndarray, *, seed: int, bar) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Measures, occupancy and a failure mask of ``solutions`` (seed ``seed + i`` for level i)."""
        from dsage_ray.core.evaluation import evaluate_with_retry

        seeds = [seed + i for i in range(len(solutions))]
        first = bar.n
        results = evaluate_with_retry(self.evaluator, solutions, seeds,
                                      progress=lambda done: bar.update(first + done - bar.n))
        failed = np.array([r.failed for r in results], dtype=bool)
        height, width = self.config.maze.height, self.config.maze.width
        measures = np.array([np.full(len(self.config.maze.measures), np.nan) if r.failed else r.measures
                             for r in results], dtype=np.float32).reshape(len(results), -1)
        occupancy = np.array([np.zeros((height, width)) if r.failed else r.occupancy for r in results],
                             dtype=np.float32).reshape(len(results), height, width)
        return measures, occupancy, failed


def offline_levels(n: int, *, domain, elites: np.ndarray | None, mutation_cells: int, random_share: float,
                   density_range: tuple[float, float], rng: np.random.Generator) -> np.ndarray:
    """``n`` valid levels: mutants of ``elites`` (``mutation_cells`` random cells redrawn, as the inner loop
    mutates) and, for ``random_share`` of them (all without elites), random valid levels at densities
    drawn from ``density_range``."""
    from dsage_ray.domains.maze.generator import random_valid_level

    out = np.zeros((n, domain.solution_dim), dtype=np.int8)
    random_rows = rng.random(n) < (1.0 if elites is None or not len(elites) else random_share)
    for i in range(n):
        while True:
            if random_rows[i]:
                level = random_valid_level(rng, height=domain.height, width=domain.width,
                                           density_range=density_range)
                out[i] = level.walls.reshape(-1)
                break
            child = elites[rng.integers(len(elites))].astype(np.int8).copy()
            cells = rng.choice(child.size, mutation_cells, replace=False)
            child[cells] = rng.integers(0, 2, mutation_cells)
            if domain.is_valid(child):
                out[i] = child
                break
    return out


def build(*, levels: int, out: str | Path, agent: str, episodes: int, elites_run: str | None, mutation_cells: int,
          random_share: float, density_range: tuple[float, float], retest_share: float, workers: int, seed: int,
          save_every: int, resume: bool) -> MazeData:
    """Evaluates ``agent`` on ``levels`` offline levels (:func:`offline_levels`) and writes them to ``out``."""
    from tqdm import tqdm

    from dsage_ray.config import RunConfig
    from dsage_ray.domains import build_domain

    config = RunConfig.build({"domain": "maze", "maze.agent": agent, "maze.episodes": episodes,
                              "ray.num_workers": max(workers, 1)})
    domain = build_domain(config)
    elites = None
    if elites_run is not None:
        state, _, _ = _run_state(elites_run)
        elites = np.asarray(state["archive"].data("solution"))
        if not len(elites):
            raise MazeDatasetError(f"{elites_run}: its archive is empty")
    rng = np.random.default_rng(seed)
    solutions = offline_levels(levels, domain=domain, elites=elites, mutation_cells=mutation_cells,
                               random_share=random_share, density_range=density_range, rng=rng)
    retest_rows = rng.random(levels) < retest_share
    done = 0
    data = MazeData(walls=np.zeros((0, domain.height, domain.width), bool),
                    measures=np.zeros((0, len(domain.measure_names)), np.float32),
                    measure_names=domain.measure_names,
                    occupancy=np.zeros((0, domain.height, domain.width), np.float32),
                    retest=np.zeros((0, len(domain.measure_names)), np.float32),
                    iteration=np.zeros(0, np.int64))
    if resume and Path(out).is_file():
        data = load(out)
        done = len(data)
        if not np.array_equal(data.solutions(), solutions[:done].astype(np.int8)):
            raise MazeDatasetError(f"{out}: its levels are not this command's first {done} (other --seed, "
                                   "--elites or level options?); not resuming")
        if data.retest is None:
            data.retest = np.full_like(data.measures, np.nan)
        print(f"resuming {out}: {done} of {levels} levels done")
    print(f"{levels} levels ({'mutants of ' + str(len(elites)) + ' elites of ' + str(elites_run) + ', ' if elites is not None else ''}"
          f"{random_share if elites is not None else 1.0:.0%} random valid), {agent}, {episodes} episodes, "
          f"{'%d Ray simulator actors' % workers if workers else 'in this process'}, {retest_rows.mean():.0%} evaluated twice")
    with Evaluator(config, workers) as evaluate, tqdm(total=levels, initial=done, desc="evaluate",
                                                      unit="level") as bar:
        while done < levels:
            stop = min(done + save_every, levels)
            chunk = solutions[done:stop]
            measures, occupancy, failed = evaluate(chunk, seed=seed * 10_000_019 + done, bar=bar)
            retest = np.full_like(measures, np.nan)
            again = np.flatnonzero(retest_rows[done:stop] & ~failed)
            if len(again):
                bar.total += len(again)
                retest[again] = evaluate(chunk[again], seed=seed * 10_000_019 + 5_000_009 + done, bar=bar)[0]
            keep = ~failed
            data = MazeData(
                walls=np.concatenate([data.walls, chunk[keep].reshape(-1, domain.height, domain.width) > 0]),
                measures=np.concatenate([data.measures, measures[keep]]), measure_names=domain.measure_names,
                occupancy=np.concatenate([data.occupancy, occupancy[keep]]),
                retest=np.concatenate([data.retest, retest[keep]]),
                iteration=np.concatenate([data.iteration, np.zeros(int(keep.sum()), np.int64)]))
            if failed.any():
                print(f"\n{int(failed.sum())} evaluation(s) failed and were left out", file=sys.stderr)
            save(data, out)
            done = stop
    return data


# ------------------------------------------------------------------------------------------- the CLI


def describe(data: MazeData) -> str:
    m = data.measure()
    values = data.measures[:, m]
    height, width = data.shape
    walls = data.walls.reshape(len(data), -1).sum(axis=1)
    lines = [f"{len(data)} levels {height}x{width}, measures {list(data.measure_names)}, occupancy "
             f"{'yes' if data.occupancy is not None else 'no'}",
             f"{PATH_LENGTH}: min {values.min():.1f}, median {np.median(values):.1f}, max {values.max():.1f}; walls "
             f"5th/50th/95th percentile {'/'.join(f'{p:.0f}' for p in np.percentile(walls, [5, 50, 95]))}"]
    if data.retest is not None:
        lines.append(f"evaluated twice: {int(np.isfinite(data.retest[:, m]).sum())} levels")
    if data.iteration is not None:
        lines.append(f"iterations: {int(data.iteration.min())}..{int(data.iteration.max())}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    convert = commands.add_parser("from-run", help="convert a finished Maze surrogate run folder")
    convert.add_argument("run", type=Path, nargs="+")
    convert.add_argument("--out", type=Path, required=True)
    convert.add_argument("--holdout-out", type=Path, help="also write the run's held-out levels here")
    convert.add_argument("--retest", type=int, default=0,
                         help="evaluate this many run levels again with the run's agent (measures_retest)")
    convert.add_argument("--seed", type=int, default=0)
    make = commands.add_parser("build", help="evaluate an agent on offline levels")
    make.add_argument("--levels", type=int, required=True)
    make.add_argument("--out", type=Path, required=True, help="an .npz outside git, e.g. tb_logs/accel_10k.npz")
    make.add_argument("--agent", default="dcd:accel")
    make.add_argument("--episodes", type=int, default=50)
    make.add_argument("--elites", help="a Maze run folder whose archive elites are mutated (default: "
                      "random valid levels only)")
    make.add_argument("--mutation-cells", type=int, default=10)
    make.add_argument("--random-share", type=float, default=0.2,
                      help="with --elites: share of random valid levels among the levels")
    make.add_argument("--density", type=float, nargs=2, default=(0.0, 0.9), metavar=("LOW", "HIGH"),
                      help="wall densities of the random valid levels")
    make.add_argument("--retest-share", type=float, default=0.1, help="share of levels evaluated twice")
    make.add_argument("--workers", type=int, default=2, help="Ray simulator actors; 0: in this process")
    make.add_argument("--seed", type=int, default=0)
    make.add_argument("--save-every", type=int, default=500)
    make.add_argument("--resume", action="store_true", help="continue a partial --out file")
    show = commands.add_parser("check", help="validate a file and describe it")
    show.add_argument("file", type=Path)
    args = parser.parse_args(argv)
    try:
        if args.command == "from-run":
            parts = [from_run(run, retest=args.retest, seed=args.seed) for run in args.run]
            data, held = parts[0] if len(parts) == 1 else (concatenate([d for d, _ in parts]),
                                                           concatenate([h for _, h in parts if h is not None]))
            print(f"{save(data, args.out)}: {describe(data)}")
            if args.holdout_out is not None:
                if held is None:
                    raise MazeDatasetError(f"{args.run}: holds no held-out levels")
                print(f"{save(held, args.holdout_out)}: {describe(held)}")
        elif args.command == "build":
            data = build(levels=args.levels, out=args.out, agent=args.agent, episodes=args.episodes,
                         elites_run=args.elites, mutation_cells=args.mutation_cells, random_share=args.random_share,
                         density_range=tuple(args.density), retest_share=args.retest_share, workers=args.workers,
                         seed=args.seed, save_every=args.save_every, resume=args.resume)
            print(f"{args.out}: {describe(data)}")
        else:
            print(f"{args.file}: {describe(load(args.file))}")
    except MazeDatasetError as exc:
        raise SystemExit(f"error: {exc}") from None


if __name__ == "__main__":
    main()
