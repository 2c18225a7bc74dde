"""GridPath: wall grids on which a breadth-first-search agent walks from the top-left to the bottom-right."""

from __future__ import annotations

import collections
import io
import shlex
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.types import EvaluationResult
from dsage_ray_gridpath.plugin import DOMAIN, GridPathConfig


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


def parse_agent(spec: str) -> int | None:
    """The moves a GridPath agent spec allows: ``bfs`` (None: no limit) or ``bfs:MOVES``.

    Raises:
        ValueError: Any other spec.
    """
    kind, _, moves = spec.strip().partition(":")
    if kind == "bfs" and (not moves or moves.isdigit()):
        return int(moves) if moves else None
    raise ValueError(f"unknown gridpath agent {spec!r} (known: bfs, bfs:MOVES with MOVES a non-negative integer)")


def format_level(walls: np.ndarray) -> str:
    """A level file: one line per row, ``#`` a wall, ``.`` a free cell."""
    return "\n".join("".join("#" if wall else "." for wall in row) for row in walls) + "\n"


def parse_level(text: str, *, source: str = "level") -> np.ndarray:
    """The wall grid of a level file :func:`format_level` wrote.

    Raises:
        ValueError: Not a square grid of ``#`` and ``.``.
    """
    rows = text.split()
    if not rows or any(len(row) != len(rows) or set(row) - {"#", "."} for row in rows):
        raise ValueError(f"{source}: not a gridpath level (a square of '#' walls and '.' free cells)")
    return np.array([[cell == "#" for cell in row] for row in rows])


#: The two measures: what the level looks like, and how much of it the agent could reach.
MEASURES = {"num_walls": lambda walls, reached: float(walls.sum()), "reachable": lambda walls, reached: float(reached)}


class GridPathDomain:
    """Levels are ``size × size`` wall bitmaps (corners always free); the objective is the agent's path
    length relative to the grid (0 when the goal is walled off), so DSAGE looks for long detours; or, in an
    audit, whether an agent that gives up after ``MOVES`` moves (``bfs:MOVES``) fails to reach a reachable goal.

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
        self.moves = parse_agent(config.agent)

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
        # The agent walks the shortest path; bfs:MOVES gives up when it is longer than MOVES moves.
        success = bool(path) and (self.moves is None or len(path) - 1 <= self.moves)
        objective = (float(bool(path) and not success) if self.config.objective == "failure"
                     else len(path) / self.solution_dim)
        return EvaluationResult(
            objective=objective,
            measures=np.array([MEASURES[m](walls, reached) for m in self.measure_names]),
            occupancy=occupancy,
            info={"path_length": len(path), "success": success},
        )

    def render(self, solution: np.ndarray, occupancy: np.ndarray | None = None) -> bytes:
        from PIL import Image

        pixels = np.where(self.walls(solution), 0, 255).astype(np.uint8)[..., None].repeat(3, axis=2)
        if occupancy is not None:
            pixels[np.asarray(occupancy) > 0] = (230, 120, 40)  # the agent's path
        buffer = io.BytesIO()
        Image.fromarray(pixels).resize((16 * self.size,) * 2, Image.NEAREST).save(buffer, format="PNG")
        return buffer.getvalue()

    # --------------------------------------------------------------------------------- audits
    # What `dsage-ray audit` and `dsage-ray compare` ask of a domain (dsage_ray.types.AuditableDomain).

    @classmethod
    def audit_values(cls, *, agent: str, reference: str | None = None, objective: str | None = None,
                     measures: Sequence[str] | None = None) -> dict[str, Any]:
        """The dotted config keys of an audit of ``agent``.

        Raises:
            ValueError: A reference agent (gridpath audits play one agent), or an unknown agent, objective
                or measure.
        """
        if reference:
            raise ValueError("gridpath audits play one agent: no --reference (compare two on a collection with "
                             "dsage-ray compare)")
        objective = objective or DOMAIN.audit.objectives[0]
        if objective not in DOMAIN.audit.objectives:
            raise ValueError(f"gridpath audit objective must be one of {DOMAIN.audit.objectives}, got {objective!r}")
        parse_agent(agent)
        measures = tuple(measures or DOMAIN.audit.measures)
        unknown = sorted(set(measures) - set(MEASURES))
        if unknown:
            raise ValueError(f"unknown gridpath measure(s) {unknown} (known: {sorted(MEASURES)})")
        return {"gridpath.agent": agent, "gridpath.objective": objective, "gridpath.measures": measures}

    def preflight(self) -> None:
        """Nothing to load: the agent is a few lines of Python (its spec was checked when the domain was built)."""

    @property
    def agent_spec(self) -> str:
        return self.config.agent

    @property
    def reference_spec(self) -> None:
        return None

    @property
    def episodes(self) -> int:
        return self.config.episodes

    def is_valid(self, solution: np.ndarray) -> bool:
        """A level is worth auditing when its goal is reachable at all."""
        return bool(shortest_path(self.walls(solution))[0])

    def success_rate(self, result: EvaluationResult) -> float:
        return float(result.info["success"])

    def reference_numbers(self, result: EvaluationResult) -> None:
        return None

    def level_text(self, solution: np.ndarray) -> str:
        return format_level(self.walls(solution))

    def entry_solution(self, entry: dict[str, Any], folder: Path) -> np.ndarray:
        path = Path(folder) / entry["level_file"]
        walls = parse_level(path.read_text(), source=str(path))
        if walls.shape != (self.size, self.size):
            raise ValueError(f"{path}: a {walls.shape[0]}x{walls.shape[1]} level, the domain's are "
                             f"{self.size}x{self.size}")
        return walls.ravel().astype(self.solution_dtype)

    def reproduce_command(self, level_file: str | Path, *, seed: int) -> str:
        """``dsage-ray gridpath eval`` (the agent is deterministic: no seed)."""
        return shlex.join(["dsage-ray", "gridpath", "eval", "--agent", self.config.agent, "--level", str(level_file)])

    def render_evaluation(self, solution: np.ndarray, result: EvaluationResult, *, title: str | None = None,
                          occupancy_max: float | None = None) -> bytes:
        return self.render(solution, result.occupancy)

    def collection_fields(self) -> dict[str, Any]:
        return {"size": self.size}

    def entry_fields(self, solution: np.ndarray, result: EvaluationResult, *, level_file: str) -> dict[str, Any]:
        return {"path_length": int(result.info["path_length"])}
