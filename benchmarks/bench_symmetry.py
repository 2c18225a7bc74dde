"""Which symmetries of the maze does the agent respect? The check before augmenting the surrogate's data with them.

Each level of a Maze dataset (``maze_dataset.py``'s ``.npz``) is evaluated as it is, again with other seeds (the
agent's test-retest), and under each of the square's 7 other symmetries (rotations by 90°, 180°, 270°, and the four
reflections), the start and goal moved with the walls. An agent that starts with a uniformly random heading and
sees the maze from its own position (ACCEL) has no preferred direction, so a rotation should change its mean path
length no more than a re-run does; a reflection swaps its left and right turns, which a trained policy need not
treat alike. Printed per transform: Spearman ρ and MAE of the mean path length against the level as it is, beside
the test-retest's::

    python benchmarks/bench_symmetry.py --data tb_logs/dsage_c16_s41.npz --levels 300

Evaluations run in this process, in batches of levels (``evaluate_levels``), one torch thread.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_surrogate_ceiling import spearman  # noqa: E402
from maze_dataset import load  # noqa: E402

#: The square's symmetries, as functions of an ``(H, W)`` array (H = W): the identity first.
TRANSFORMS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "identity": lambda a: a,
    "rotate 90": lambda a: np.rot90(a, 1),
    "rotate 180": lambda a: np.rot90(a, 2),
    "rotate 270": lambda a: np.rot90(a, 3),
    "flip left-right": np.fliplr,
    "flip up-down": np.flipud,
    "transpose": lambda a: a.T,
    "anti-transpose": lambda a: np.rot90(a, 2).T,
}


def moved_cell(transform: Callable[[np.ndarray], np.ndarray], shape: tuple[int, int],
               cell: tuple[int, int]) -> tuple[int, int]:
    """Where ``cell`` of an ``shape`` array lands under ``transform``."""
    index = np.arange(shape[0] * shape[1]).reshape(shape)
    row, col = np.argwhere(transform(index) == index[cell])[0]
    return int(row), int(col)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True, help="a Maze dataset (.npz)")
    parser.add_argument("--levels", type=int, default=300, help="the first N levels of the file")
    parser.add_argument("--agent", default="dcd:accel")
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--batch", type=int, default=50, help="levels per evaluation batch")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    import torch

    from dsage_ray.domains.maze.agents import load_maze_agent
    from dsage_ray.domains.maze.evaluate import evaluate_levels
    from dsage_ray.domains.maze.level import MazeLevel

    torch.set_num_threads(1)
    data = load(args.data)
    walls = data.walls[: args.levels]
    if walls.shape[1] != walls.shape[2]:
        print(f"{args.data}: the levels are {walls.shape[1]}x{walls.shape[2]}; only square mazes have these "
              "symmetries", file=sys.stderr)
        return 2
    agent = load_maze_agent(args.agent)
    base = [MazeLevel.from_bitmap(w) for w in walls]
    base = [level for level in base if level.valid]
    shape = walls.shape[1:]

    def path_lengths(levels: list[MazeLevel], seed: int) -> np.ndarray:
        values = []
        for first in range(0, len(levels), args.batch):
            batch = levels[first:first + args.batch]
            values += [e.mean_path_length for e in evaluate_levels(batch, agent, episodes=args.episodes,
                                                                     seed=seed + first)]
        return np.asarray(values)

    print(f"{len(base)} valid levels of {args.data}, {args.agent}, {args.episodes} episodes each")
    started = time.perf_counter()
    reference = path_lengths(base, args.seed)
    retest = path_lengths(base, args.seed + 100_000)
    print("| level | Spearman ρ with the level as it is | MAE (steps) |")
    print("|---|---|---|")
    print(f"| as it is, other seeds (test-retest) | {spearman(reference, retest):.3f} | "
          f"{np.abs(reference - retest).mean():.1f} |")
    for name, transform in list(TRANSFORMS.items())[1:]:
        moved = [MazeLevel.from_bitmap(transform(level.walls), start=moved_cell(transform, shape, level.start),
                                       goal=moved_cell(transform, shape, level.goal)) for level in base]
        values = path_lengths(moved, args.seed + 100_000)
        print(f"| {name} | {spearman(reference, values):.3f} | {np.abs(reference - values).mean():.1f} |")
    print(f"({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
