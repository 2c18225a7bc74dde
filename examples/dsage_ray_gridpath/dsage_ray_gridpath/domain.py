"""GridPath: wall grids on which a breadth-first-search agent walks from the top-left to the bottom-right."""

from __future__ import annotations

import collections
import io

import numpy as np

from dsage_ray.types import EvaluationResult
from dsage_ray_gridpath.plugin import GridPathConfig


def shortest_path(walls: np.ndarray) -> tuple[list[tuple[int, int]], int]:
    """The simulator: BFS from the top-left corner; the path to the bottom-right (empty when walled off)
    and how many cells the search reached."""
    n = walls.shape[0]
    parent = {(0, 0): None}
    queue = collections.deque([(0, 0)])
    while queue:
        r, c = queue.popleft()
        for cell in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if 0 <= cell[0] < n and 0 <= cell[1] < n and not walls[cell] and cell not in parent:
                parent[cell] = (r, c)
                queue.append(cell)
    path, cell = [], (n - 1, n - 1) if (n - 1, n - 1) in parent else None
    while cell is not None:
        path.append(cell)
        cell = parent[cell]
    return path[::-1], len(parent)


#: The two measures: what the level looks like, and how much of it the agent could reach.
MEASURES = {"num_walls": lambda walls, reached: float(walls.sum()), "reachable": lambda walls, reached: float(reached)}


class GridPathDomain:
    """Levels are ``size × size`` wall bitmaps (corners always free); the objective is the agent's path
    length relative to the grid (0 when the goal is walled off), so DSAGE looks for long detours.

    Args:
        config: The ``gridpath`` section of a run config.
    """

    name = "gridpath"
    solution_dtype = np.int8
    encoding_channels = 2  # floor, wall
    encoding_pad_channel = 1  # the surrogate pads a level with walls

    def __init__(self, *, config: GridPathConfig):
        self.config, self.size = config, config.size
        self.solution_dim = self.size * self.size
        self.measure_names = tuple(config.measures)
        unknown = sorted(set(self.measure_names) - set(MEASURES))
        if unknown:
            raise ValueError(f"gridpath.measures: unknown {unknown} (known: {sorted(MEASURES)})")
        self.measure_ranges = tuple(map(tuple, config.measure_ranges)) or ((0.0, float(self.solution_dim)),) * 2
        self.archive_dims = tuple(config.archive_dims)
        self.occupancy_shape = (self.size, self.size)

    def walls(self, solution: np.ndarray) -> np.ndarray:
        walls = np.asarray(solution).reshape(self.size, self.size) > 0.5
        walls[0, 0] = walls[-1, -1] = False
        return walls

    def random_solutions(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """The generator: independent walls with probability ``density``."""
        return (rng.random((n, self.solution_dim)) < self.config.density).astype(self.solution_dtype)

    random_valid_solutions = random_solutions  # every grid is a level

    def encode(self, solutions: np.ndarray) -> np.ndarray:
        walls = np.asarray(solutions, dtype=np.float32).reshape(-1, self.size, self.size) > 0.5
        return np.stack([~walls, walls], axis=1).astype(np.float32)

    def evaluate(self, solution: np.ndarray, seed: int) -> EvaluationResult:
        walls = self.walls(solution)
        path, reached = shortest_path(walls)
        occupancy = np.zeros(self.occupancy_shape, dtype=np.float32)
        for cell in path:
            occupancy[cell] = 1.0
        return EvaluationResult(
            objective=len(path) / self.solution_dim,
            measures=np.array([MEASURES[m](walls, reached) for m in self.measure_names]),
            occupancy=occupancy,
            info={"path_length": len(path)},
        )

    def render(self, solution: np.ndarray, occupancy: np.ndarray | None = None) -> bytes:
        from PIL import Image

        pixels = np.where(self.walls(solution), 0, 255).astype(np.uint8)[..., None].repeat(3, axis=2)
        if occupancy is not None:
            pixels[np.asarray(occupancy) > 0] = (230, 120, 40)  # the agent's path
        buffer = io.BytesIO()
        Image.fromarray(pixels).resize((16 * self.size,) * 2, Image.NEAREST).save(buffer, format="PNG")
        return buffer.getvalue()
