import numpy as np
import pytest

from dsage_ray.qd import MapElitesBitmapEmitter, RandomEmitter
from tests.qd.helpers import DIM, bitmap_predict, bitmap_sampler


def _fill(archive, rng, n=200):
    solutions = rng.integers(0, 2, size=(n, DIM))
    objective, measures, extra = bitmap_predict(solutions)
    archive.add(solutions, objective, measures, **extra)


def test_first_batches_are_random_then_mutations(bitmap_archive):
    emitter = MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=20, mutation_cells=3,
                                     initial_random_batches=2, seed=0)
    _fill(bitmap_archive, np.random.default_rng(1))
    elites = {tuple(s) for s in bitmap_archive.data("solution")}
    random_batches = [emitter.ask() for _ in range(2)]
    # Random batches come from the emitter's RNG, not from elites: a fresh emitter with the same seed
    # reproduces them exactly, whatever the archive holds.
    twin = MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=20, mutation_cells=3,
                                  initial_random_batches=2, seed=0)
    for batch in random_batches:
        np.testing.assert_array_equal(batch, twin.ask())
    # After the random batches every child is within 3 cells of some elite (its parent).
    for _ in range(5):
        batch = emitter.ask()
        assert batch.shape == (20, DIM) and batch.dtype == np.int8
        assert set(np.unique(batch)) <= {0, 1}
        for child in batch:
            distance = min(np.sum(child != np.array(e)) for e in elites)
            assert distance <= 3


def test_mutation_changes_at_most_mutation_cells_of_the_parent(bitmap_archive):
    # One elite in the archive: every offspring's parent is known.
    parent = np.zeros((1, DIM), dtype=np.int8)
    objective, measures, extra = bitmap_predict(parent)
    bitmap_archive.add(parent, objective, measures, **extra)
    emitter = MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=500, mutation_cells=4,
                                     initial_random_batches=0, seed=2)
    changed = (emitter.ask() != 0).sum(axis=1)
    assert changed.max() == 4  # exactly 4 cells redrawn; all redrawn to 1 happens with p=1/16 per child
    assert changed.min() >= 0
    # Each redrawn cell is 1 with probability 1/2: mean changed cells ≈ 2.
    assert abs(changed.mean() - 2.0) < 0.2


def test_mutated_cells_are_distinct_and_uniform(bitmap_archive):
    parent = np.zeros((1, DIM), dtype=np.int8)
    bitmap_archive.add(parent, *bitmap_predict(parent)[:2], **bitmap_predict(parent)[2])
    emitter = MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=4000, mutation_cells=DIM,
                                     initial_random_batches=0, seed=5)
    # mutation_cells == solution_dim: all cells redrawn, so every cell is 1 about half the time.
    freq = emitter.ask().mean(axis=0)
    assert np.all(np.abs(freq - 0.5) < 0.05)


def test_random_batches_while_archive_empty(bitmap_archive):
    emitter = MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=8, initial_random_batches=0, seed=0)
    batch = emitter.ask()  # no elites to mutate yet: falls back to random bitmaps
    assert batch.shape == (8, DIM) and set(np.unique(batch)) <= {0, 1}


def test_bitmap_emitter_validates_arguments(bitmap_archive):
    with pytest.raises(ValueError, match="solution_dim"):
        MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM + 1, batch_size=4, seed=0)
    with pytest.raises(ValueError, match="mutation_cells"):
        MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=4, mutation_cells=DIM + 1, seed=0)
    emitter = MapElitesBitmapEmitter(bitmap_archive, solution_dim=DIM, batch_size=4, seed=0)
    np.testing.assert_array_equal(emitter.lower_bounds, 0)
    np.testing.assert_array_equal(emitter.upper_bounds, 1)


def test_random_emitter_always_samples_the_domain(bitmap_archive):
    emitter = RandomEmitter(bitmap_archive, sampler=bitmap_sampler, batch_size=6, seed=9)
    rng = np.random.default_rng(9)
    _fill(bitmap_archive, np.random.default_rng(0))  # elites must not matter
    for _ in range(3):
        np.testing.assert_array_equal(emitter.ask(), bitmap_sampler(6, rng))
    # int8 archive: bounds are int8's range, not ±inf silently cast to 0.
    assert emitter.lower_bounds.min() == -128 and emitter.upper_bounds.max() == 127


def test_random_emitter_rejects_wrong_shape(bitmap_archive):
    emitter = RandomEmitter(bitmap_archive, sampler=lambda n, rng: np.zeros((n, DIM + 1)), batch_size=2, seed=0)
    with pytest.raises(ValueError, match="shape"):
        emitter.ask()
