"""Small deterministic stand-ins for a domain, so the algorithm can be tested without simulators."""

from __future__ import annotations

import dataclasses

import numpy as np

from dsage_ray.types import EvaluationResult

#: A DSAGE run on :class:`BitmapDomain` small enough to finish in seconds (``RunConfig.build`` keys).
SMALL_RUN = {
    "budget": 70,
    "n_rand": 40,
    "surrogate.epochs": 1,
    "surrogate.batch_size": 16,
    "qd.exploit_iterations": 4,
    "qd.num_emitters": 2,
    "qd.batch_size": 10,
    "maze.archive_dims": (16, 8),
    "selection.block": (4, 2),
    "selection.count": 25,
}


class BitmapDomain:
    """An 8×8 wall bitmap whose "agent" is a pure function of the level and the seed.

    Objective: share of empty cells in the first row. Measures: number of walls and number of
    walls in the top half. Occupancy: empty cells, scaled by a seed-dependent factor, so that
    the surrogate has a learnable ancillary target.

    Args:
        fail_on: Evaluations whose solution sums to one of these values raise (fault injection).
        fail_once: Raise only the first time such a solution is seen.
    """

    name = "bitmap"
    solution_dim = 64
    measure_names = ("num_walls", "top_walls")
    measure_ranges = ((0.0, 64.0), (0.0, 32.0))
    archive_dims = (16, 8)
    occupancy_shape = (8, 8)
    encoding_channels = 2
    encoding_pad_channel = 0
    solution_dtype = np.int8

    def __init__(self, *, fail_on: tuple[int, ...] = (), fail_once: bool = True) -> None:
        self.fail_on = set(fail_on)
        self.fail_once = fail_once
        self.calls = 0
        self._failed: set[bytes] = set()

    def random_solutions(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return rng.integers(0, 2, size=(n, self.solution_dim)).astype(np.int8)

    random_valid_solutions = random_solutions  # every bitmap is a level

    def encode(self, solutions: np.ndarray) -> np.ndarray:
        walls = np.asarray(solutions, dtype=np.float32).reshape(-1, 8, 8)
        return np.stack([1.0 - walls, walls], axis=1)

    #: The fake's work count: its "agent" walks every empty cell.
    work_names = ("steps",)

    def work_counts(self, result: EvaluationResult) -> dict[str, float]:
        return {"steps": float(result.occupancy.astype(bool).sum())}

    def evaluate(self, solution: np.ndarray, seed: int) -> EvaluationResult:
        self.calls += 1
        walls = np.asarray(solution).reshape(8, 8) > 0.5
        key = walls.tobytes()
        if int(walls.sum()) in self.fail_on and not (self.fail_once and key in self._failed):
            self._failed.add(key)
            raise RuntimeError(f"injected failure for a level with {int(walls.sum())} walls")
        jitter = np.random.default_rng(seed).uniform(0.9, 1.1)
        return EvaluationResult(
            objective=float(1.0 - walls[0].mean()),
            measures=np.array([walls.sum(), walls[:4].sum()], dtype=np.float64),
            occupancy=((~walls) * jitter).astype(np.float32),
            info={"seed": seed},
        )

    def render(self, solution: np.ndarray, occupancy: np.ndarray | None) -> bytes:
        import io

        from PIL import Image

        image = Image.fromarray(np.asarray(solution, dtype=np.uint8).reshape(8, 8) * np.uint8(255))
        buffer = io.BytesIO()
        image.save(buffer, format="PNG")
        return buffer.getvalue()


class ScreeningBitmapDomain(BitmapDomain):
    """:class:`BitmapDomain` with a screen (``selection.screen_episodes``) and, as in the Maze's QD search, the
    same objective for every level, so that an evaluation adds to the archive only by filling a new cell. Its
    measures are functions of the level alone: the screen is exact, and a screened pick lands where it said."""

    def __init__(self, **options) -> None:
        super().__init__(**options)
        self.screened = 0

    def evaluate(self, solution: np.ndarray, seed: int) -> EvaluationResult:
        return dataclasses.replace(super().evaluate(solution, seed), objective=1.0)

    def screen(self, solutions: np.ndarray, *, episodes: int, seed: int,
               precision: str = "fp32") -> list[EvaluationResult]:
        self.screened += len(solutions)
        results = [self.evaluate(solution, seed + i) for i, solution in enumerate(solutions)]
        self.calls -= len(solutions)  # a screen is not an evaluation
        return results
