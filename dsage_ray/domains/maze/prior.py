"""Parameter-free priors of the Maze measures, for the surrogate's ``prior_measure`` (not in the paper).

A uniform random walker's expected steps from the start to the goal (its hitting time) ranks ACCEL's mean
path length better than the shortest path, and as well as a surrogate trained on 1,600 of a search's own
levels (``docs/results/surrogate_accuracy``). It is exact and costs one banded solve per level.
"""

from __future__ import annotations

from typing import Callable

import torch

from dsage_ray.domains.maze.encoding import EMPTY, GOAL, START
from dsage_ray.surrogate.grid_features import RandomWalkFields

#: The measure each prior predicts, by name.
PRIORS = ("mean_path_length",)


def walker_prior(measure: str) -> Callable[[torch.Tensor], torch.Tensor] | None:
    """The prior of ``measure``: encoded Maze levels ``(n, C, S, S)`` → ``(n,)`` float64, or None without one."""
    if measure not in PRIORS:
        return None
    walker = RandomWalkFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=1.0)

    def hitting_time(levels: torch.Tensor) -> torch.Tensor:
        return walker.visits(levels).sum(dim=(1, 2))

    return hitting_time
