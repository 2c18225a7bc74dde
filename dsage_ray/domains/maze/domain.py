"""The Maze domain behind the :class:`~dsage_ray.types.Domain` protocol."""

from __future__ import annotations

from typing import Any

import numpy as np

from dsage_ray.config import MazeConfig
from dsage_ray.domains.maze.encoding import CHANNELS, SPARE, encode_levels
from dsage_ray.domains.maze.evaluate import MazeEvaluation, evaluate
from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.measures import get_measure, get_objective
from dsage_ray.types import EncodedLevels, EvaluationResult, Solution, Solutions


class MazeDomain:
    """Wall bitmaps searched for how one agent behaves on them (SPEC §2).

    A solution is a flattened ``H·W`` bitmap (values > 0.5 are walls); its start and goal are the
    furthest connected pair. The agent is loaded lazily, once per domain object, so building a
    domain is cheap and the object pickles without it.

    Args:
        config: The Maze section of a run config.
    """

    name = "maze"
    #: Bitmaps are 0/1: archives and datasets keep them as int8 (256 bytes per 16×16 elite).
    solution_dtype = np.int8

    def __init__(self, *, config: MazeConfig):
        self.config = config
        self.height, self.width = config.height, config.width
        self.solution_dim = self.height * self.width
        self.measure_names = tuple(config.measures)
        # Looked up now so a bad name fails at construction; kept by name so the domain pickles.
        measures = [get_measure(name) for name in self.measure_names]
        get_objective(config.objective)
        self.measure_ranges = tuple(tuple(map(float, r)) for r in config.measure_ranges) or tuple(
            m.natural_range(self.height, self.width) for m in measures
        )
        # 0 cells means one cell per integer value of the measure (e.g. 256 for 0..256 walls).
        self.archive_dims = tuple(
            d if d > 0 else max(1, int(round(high - low)))
            for d, (low, high) in zip(config.archive_dims, self.measure_ranges)
        )
        self.occupancy_shape = (self.height, self.width)
        self.encoding_channels = len(CHANNELS)
        # Sizes that are not a square power of two get padded for the surrogate: padding cells
        # are marked "spare", which no real cell uses, so they never look like floor or wall.
        self.encoding_pad_channel = SPARE
        self._agent = None

    @property
    def agent(self):
        """The agent ``config.agent`` names, loaded on first use."""
        if self._agent is None:
            from dsage_ray.agents import load_agent

            self._agent = load_agent(self.config.agent)
        return self._agent

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_agent"] = None  # agents hold torch modules; each process loads its own
        return state

    def level(self, solution: Solution) -> MazeLevel:
        """The level a solution describes."""
        bitmap = np.asarray(solution).reshape(self.height, self.width) > 0.5
        return MazeLevel.from_bitmap(bitmap)

    def random_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """``n`` uniformly random bitmaps, 0/1 rows of :attr:`solution_dtype`."""
        return rng.integers(0, 2, size=(n, self.solution_dim)).astype(self.solution_dtype)

    def random_valid_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """``n`` valid levels from the project's random-valid-maze distribution (the surrogate's held-out set)."""
        from dsage_ray.domains.maze.generator import random_valid_level

        levels = [random_valid_level(rng, height=self.height, width=self.width) for _ in range(n)]
        return np.array([level.walls.ravel() for level in levels], dtype=self.solution_dtype).reshape(n, -1)

    def encode(self, solutions: Solutions) -> EncodedLevels:
        return encode_levels(np.asarray(solutions).reshape(-1, self.solution_dim), self.height, self.width)

    def run(self, solution: Solution, seed: int) -> MazeEvaluation:
        """The full evaluation of one solution (the agent is not loaded for an invalid level)."""
        level = self.level(solution)
        return evaluate(level, self.agent if level.valid else None, episodes=self.config.episodes, seed=seed,
                        see_through_walls=self.config.see_through_walls)

    def evaluate(self, solution: Solution, seed: int) -> EvaluationResult:
        result = self.run(solution, seed)
        return EvaluationResult(
            objective=float(get_objective(self.config.objective)(result)),
            measures=np.array([get_measure(name).fn(result) for name in self.measure_names], dtype=np.float64),
            occupancy=result.occupancy,
            info={
                key: value for key, value in result.to_dict().items()
                if key in ("success_rate", "mean_path_length", "episode_lengths", "successes",
                           "optimal_path_length", "start", "goal", "valid", "explored_fraction", "repeated_visits")
            },
        )

    def render(self, solution: Solution, occupancy: np.ndarray | None = None) -> bytes:
        """A PNG of the level, with ``occupancy`` overlaid when given."""
        from dsage_ray.domains.maze.render import render_level

        return render_level(self.level(solution), occupancy)
