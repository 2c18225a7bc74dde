"""Fake domain pieces shared by the QD tests (kept tiny: the test machine is shared)."""

from __future__ import annotations

import numpy as np

from dsage_ray.qd import make_archive

DIM = 16  # a 4×4 bitmap
OCC = (4, 4)


def bitmap_sampler(n: int, rng: np.random.Generator) -> np.ndarray:
    """Module-level (hence picklable) domain sampler: uniform 0/1 bitmaps."""
    return rng.integers(0, 2, size=(n, DIM))


def box_sampler(n: int, rng: np.random.Generator) -> np.ndarray:
    """Module-level (hence picklable) sampler of a continuous domain: uniform in [-1, 1]^DIM."""
    return rng.uniform(-1.0, 1.0, size=(n, DIM))


def bitmap_predict(solutions: np.ndarray):
    """Deterministic fake surrogate: measures spread the bitmaps over a 16×8 archive."""
    x = np.asarray(solutions, dtype=np.float64)
    walls = x.sum(axis=1)
    weighted = (x * np.arange(1, DIM + 1)).sum(axis=1) % 8
    objective = (x[:, 0] + x[:, -1]) / 2
    occupancy = x.reshape(-1, *OCC).astype(np.float32)
    return objective, np.stack([walls, weighted], axis=1), {"occupancy": occupancy}


def latent_predict(solutions: np.ndarray):
    """Fake surrogate for continuous latents: a sphere objective, tanh measures."""
    x = np.asarray(solutions, dtype=np.float64)
    occupancy = np.zeros((len(x), *OCC), dtype=np.float32)
    return -np.sum(x**2, axis=1), np.tanh(x[:, :2]) * 8 + 8, {"occupancy": occupancy}


def make_bitmap_archive(seed: int = 3, dims=(16, 8)):
    return make_archive(solution_dim=DIM, dims=dims, ranges=[(0, 16), (0, 8)], occupancy_shape=OCC, seed=seed,
                        solution_dtype=np.int8)


def make_latent_archive(seed: int = 3):
    return make_archive(solution_dim=DIM, dims=(16, 8), ranges=[(0, 16), (0, 8)], occupancy_shape=OCC, seed=seed)


def checkpoint_round_trip(obj, folder):
    """``obj`` written to and read back from a checkpoint file in ``folder`` (the format runs are saved in)."""
    from dsage_ray.core.checkpoint import load_checkpoint, save_checkpoint

    return load_checkpoint(save_checkpoint({"state": obj}, folder / "round_trip.dsage"))["state"]
