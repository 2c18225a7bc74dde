"""Every real evaluation DSAGE has made, as training data for the surrogate (SPEC: DSAGE and the surrogate).

Levels are stored bit-packed: the surrogate's inputs are one-hot (0/1), so one bit per value
holds them exactly. A 5×16×16 Maze level takes 160 bytes instead of 5 KiB as float32 (100k Maze
samples: 16 MB of levels + 100 MB of float32 occupancy), and a padded 17×64×64 Mario level 8.5 KiB
instead of 272 KiB. Minibatches are unpacked on demand. Levels that are parameter vectors ``(P, 1, 1)`` (the gym
domain's, real numbers) are kept as float32.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Sequence

import numpy as np
import torch

from dsage_ray.types import EncodedLevels, EvaluationResult, Solutions


@dataclasses.dataclass
class Targets:
    """Ground truth of the successful evaluations in a batch.

    Attributes:
        valid: Boolean mask over the batch: False for failed evaluations (their values are
            placeholders, not data, so they are neither trained on nor scored).
        objective: Shape ``(k,)`` float64, ``k = valid.sum()``.
        measures: Shape ``(k, num_measures)`` float64.
        occupancy: Shape ``(k, H, W)`` float32.
    """

    valid: np.ndarray
    objective: np.ndarray
    measures: np.ndarray
    occupancy: np.ndarray

    @classmethod
    def from_results(cls, results: Sequence[EvaluationResult], *, num_measures: int,
                     occupancy_shape: tuple[int, int]) -> "Targets":
        valid = np.array([not r.failed for r in results], dtype=bool)
        kept = [r for r in results if not r.failed]
        objective = np.array([r.objective for r in kept], dtype=np.float64)
        measures = np.array([r.measures for r in kept], dtype=np.float64).reshape(len(kept), num_measures)
        occupancy = np.array([r.occupancy for r in kept], dtype=np.float32).reshape(len(kept), *occupancy_shape)
        return cls(valid=valid, objective=objective, measures=measures, occupancy=occupancy)


class TrainingWindow:
    """A read-only view of the most recent samples, unpacked into tensors one minibatch at a time."""

    def __init__(self, *, packed: np.ndarray, level_shape: tuple[int, int, int], objective: np.ndarray,
                 measures: np.ndarray, occupancy: np.ndarray) -> None:
        self._packed = packed
        self._level_shape = level_shape
        self.objective = objective
        self.measures = measures
        self.occupancy = occupancy

    def __len__(self) -> int:
        return len(self.objective)

    def batch(self, indices: np.ndarray, device: torch.device) -> tuple[torch.Tensor, ...]:
        """Levels ``(b, C, S, S)``, objective ``(b,)``, measures ``(b, m)``, occupancy ``(b, H, W)``, float32."""
        levels = _unpack(self._packed[indices], self._level_shape)
        arrays = (levels, self.objective[indices], self.measures[indices], self.occupancy[indices])
        return tuple(torch.from_numpy(np.asarray(a, dtype=np.float32)).to(device) for a in arrays)


class SurrogateDataset:
    """Append-only store of (level, objective, measures, occupancy[, solution]) per evaluation.

    Args:
        level_shape: ``(channels, size, size)`` of the encoded levels the surrogate reads.
        num_measures: Measures per evaluation.
        occupancy_shape: ``(H, W)`` of the occupancy grid.
        solution_dim: When set, the solutions are kept too (for analysis; training does not need them).
        solution_dtype: dtype to keep solutions in (``np.uint8`` suits Maze bitmaps).
    """

    def __init__(self, *, level_shape: tuple[int, int, int], num_measures: int, occupancy_shape: tuple[int, int],
                 solution_dim: int | None = None, solution_dtype: Any = np.float64) -> None:
        self.level_shape = tuple(int(d) for d in level_shape)
        self.num_measures = int(num_measures)
        self.occupancy_shape = tuple(int(d) for d in occupancy_shape)
        self.solution_dim = solution_dim
        self.solution_dtype = np.dtype(solution_dtype)
        self._size = 0
        self._arrays = self._allocate(0)

    # ------------------------------------------------------------------------------------ storage

    @property
    def _packed_bytes(self) -> int:
        return (int(np.prod(self.level_shape)) + 7) // 8

    def _allocate(self, capacity: int) -> dict[str, np.ndarray]:
        arrays = {
            "levels": (np.zeros((capacity, self.level_shape[0]), dtype=np.float32) if _dense(self.level_shape)
                       else np.zeros((capacity, self._packed_bytes), dtype=np.uint8)),
            "objective": np.zeros(capacity, dtype=np.float64),
            "measures": np.zeros((capacity, self.num_measures), dtype=np.float64),
            "occupancy": np.zeros((capacity, *self.occupancy_shape), dtype=np.float32),
        }
        if self.solution_dim is not None:
            arrays["solutions"] = np.zeros((capacity, self.solution_dim), dtype=self.solution_dtype)
        return arrays

    def _reserve(self, capacity: int) -> None:
        # Geometric growth keeps appends amortised O(1) over a 100k-evaluation run.
        if capacity <= len(self._arrays["objective"]):
            return
        grown = self._allocate(max(capacity, 2 * len(self._arrays["objective"])))
        for key, array in self._arrays.items():
            grown[key][:self._size] = array[:self._size]
        self._arrays = grown

    def __len__(self) -> int:
        return self._size

    def append(self, *, encoded: EncodedLevels, results: Sequence[EvaluationResult],
               solutions: Solutions | None = None) -> int:
        """Stores the successful evaluations of a batch.

        Args:
            encoded: The evaluated levels as the surrogate reads them, ``(n, *level_shape)``, 0/1 values (any values
                for parameter vectors).
            results: One result per level; failed ones are skipped (they hold placeholders, not data).
            solutions: ``(n, solution_dim)``; required when the dataset keeps solutions.

        Returns:
            How many samples were stored.
        """
        encoded = np.asarray(encoded)
        if encoded.shape[1:] != self.level_shape or len(encoded) != len(results):
            raise ValueError(f"expected {len(results)} levels of shape {self.level_shape}, got {encoded.shape}")
        dense = _dense(self.level_shape)
        if not dense and not np.all((encoded == 0) | (encoded == 1)):
            raise ValueError("encoded levels must be one-hot (0/1 values) to be stored bit-packed")
        if (solutions is None) != (self.solution_dim is None):
            raise ValueError("pass solutions exactly when the dataset was built with solution_dim")
        targets = Targets.from_results(results, num_measures=self.num_measures,
                                       occupancy_shape=self.occupancy_shape)
        count = len(targets.objective)
        start, stop = self._size, self._size + count
        self._reserve(stop)
        kept = encoded[targets.valid].reshape(count, -1)
        self._arrays["levels"][start:stop] = kept if dense else np.packbits(kept.astype(bool), axis=1)
        self._arrays["objective"][start:stop] = targets.objective
        self._arrays["measures"][start:stop] = targets.measures
        self._arrays["occupancy"][start:stop] = targets.occupancy
        if solutions is not None:
            self._arrays["solutions"][start:stop] = np.asarray(solutions)[targets.valid]
        self._size = stop
        return count

    # ------------------------------------------------------------------------------------ reading

    def recent(self, k: int) -> TrainingWindow:
        """The most recent ``min(k, len(self))`` samples, oldest first."""
        start = max(0, self._size - k)
        view = {key: array[start:self._size] for key, array in self._arrays.items()}
        return TrainingWindow(packed=view["levels"], level_shape=self.level_shape, objective=view["objective"],
                              measures=view["measures"], occupancy=view["occupancy"])

    def levels(self, indices: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Unpacked float32 levels of the samples at ``indices``."""
        return _unpack(self._arrays["levels"][:self._size][indices], self.level_shape)

    @property
    def objective(self) -> np.ndarray:
        return self._arrays["objective"][:self._size]

    @property
    def measures(self) -> np.ndarray:
        return self._arrays["measures"][:self._size]

    @property
    def occupancy(self) -> np.ndarray:
        return self._arrays["occupancy"][:self._size]

    @property
    def solutions(self) -> np.ndarray | None:
        return self._arrays["solutions"][:self._size] if self.solution_dim is not None else None

    # ------------------------------------------------------------------------------- checkpoints

    def state_dict(self) -> dict[str, Any]:
        """Plain numpy arrays (copies, trimmed to the stored samples); picklable."""
        state: dict[str, Any] = {key: array[:self._size].copy() for key, array in self._arrays.items()}
        state["level_shape"] = self.level_shape
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if tuple(state["level_shape"]) != self.level_shape:
            raise ValueError(f"checkpoint levels are {tuple(state['level_shape'])}, dataset expects {self.level_shape}")
        if ("solutions" in state) != (self.solution_dim is not None):
            raise ValueError("checkpoint and dataset disagree on whether solutions are kept")
        size = len(state["objective"])
        arrays = self._allocate(size)
        for key in arrays:
            if state[key].shape[1:] != arrays[key].shape[1:]:
                raise ValueError(f"checkpoint {key} has shape {state[key].shape}, expected (*, {arrays[key].shape[1:]})")
            arrays[key][:] = state[key]
        self._arrays, self._size = arrays, size


def _dense(level_shape: tuple[int, ...]) -> bool:
    """Parameter vectors ``(P, 1, 1)`` are real numbers, stored as they are; one-hot grids are bit-packed."""
    return tuple(level_shape[1:]) == (1, 1)


def _unpack(packed: np.ndarray, level_shape: tuple[int, int, int]) -> np.ndarray:
    if _dense(level_shape):
        return np.asarray(packed, dtype=np.float32).reshape(len(packed), *level_shape)
    bits = np.unpackbits(packed, axis=1, count=int(np.prod(level_shape)))
    return bits.reshape(len(packed), *level_shape).astype(np.float32)
