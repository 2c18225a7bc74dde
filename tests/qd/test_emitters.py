import numpy as np
import pytest
from ribs.emitters import GaussianEmitter
from ribs.schedulers import Scheduler
from scipy.stats import qmc

from dsage_ray.config import QDConfig
from dsage_ray.qd import CrossEntropyEmitter, HaltonEmitter, MapElitesBitmapEmitter, RandomEmitter, make_emitters
from tests.qd.helpers import (DIM, bitmap_predict, bitmap_sampler, box_sampler, checkpoint_round_trip,
                              latent_predict, make_latent_archive)


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


# The continuous searches of a box ([-1, 1]^DIM here), built as `qd.emitter` builds them.
BOX_EMITTERS = {"gaussian": GaussianEmitter, "halton": HaltonEmitter, "cross_entropy": CrossEntropyEmitter}


def _box_emitter(kind, seed, archive=None, batch_size=8):
    archive = make_latent_archive() if archive is None else archive
    config = QDConfig(emitter=kind, num_emitters=1, batch_size=batch_size)
    (emitter,) = make_emitters(archive, config=config, solution_dim=DIM, random_solutions=box_sampler, seed=seed,
                               bounds=(-1.0, 1.0))
    return emitter


def _run(emitter, rounds):
    """``rounds`` ask → tell rounds through a scheduler over the emitter's archive; the asked batches."""
    scheduler = Scheduler(emitter.archive, [emitter])
    batches = []
    for _ in range(rounds):
        batch = scheduler.ask()
        objective, measures, extra = latent_predict(batch)
        scheduler.tell(objective, measures, **extra)
        batches.append(batch)
    return batches


@pytest.mark.parametrize("kind", sorted(BOX_EMITTERS))
def test_box_emitters_keep_inside_the_box_and_follow_their_seed(kind):
    emitter = _box_emitter(kind, seed=4)
    assert type(emitter) is BOX_EMITTERS[kind]
    np.testing.assert_array_equal(emitter.lower_bounds, -1.0)
    np.testing.assert_array_equal(emitter.upper_bounds, 1.0)
    batches = _run(emitter, 6)
    for batch in batches:
        assert batch.shape == (8, DIM) and batch.dtype == np.float64
        assert batch.min() >= -1.0 and batch.max() <= 1.0
    np.testing.assert_array_equal(np.stack(batches), np.stack(_run(_box_emitter(kind, seed=4), 6)))
    assert not np.array_equal(np.stack(batches), np.stack(_run(_box_emitter(kind, seed=5), 6)))


@pytest.mark.parametrize("kind", sorted(BOX_EMITTERS))
def test_box_emitters_continue_unchanged_after_a_checkpoint(kind, tmp_path):
    emitter = _box_emitter(kind, seed=7)
    _run(emitter, 3)
    restored = checkpoint_round_trip(emitter, tmp_path)
    np.testing.assert_array_equal(np.stack(_run(emitter, 3)), np.stack(_run(restored, 3)))


def test_halton_is_one_scrambled_sequence_across_asks_and_pickles(latent_archive, tmp_path):
    emitter = HaltonEmitter(latent_archive, bounds=(-2.0, 3.0), batch_size=5, seed=11)
    first = emitter.ask()
    restored = checkpoint_round_trip(emitter, tmp_path)  # mid-sequence
    assert emitter.num_generated == restored.num_generated == 5
    second, resumed = emitter.ask(), restored.ask()
    np.testing.assert_array_equal(second, resumed)
    expected = -2.0 + 5.0 * qmc.Halton(d=DIM, scramble=True, rng=11).random(10)
    np.testing.assert_allclose(np.concatenate([first, second]), expected)
    assert emitter.num_generated == 10 and emitter.batch_size == 5
    assert first.min() >= -2.0 and first.max() <= 3.0


def test_halton_covers_the_box_more_evenly_than_uniform_draws(latent_archive):
    # Low discrepancy: every one of 8 bins per coordinate gets about its share of 64 points.
    points = HaltonEmitter(latent_archive, batch_size=32, seed=0)
    sample = np.concatenate([points.ask(), points.ask()])
    counts = np.stack([np.histogram(sample[:, d], bins=8, range=(-1, 1))[0] for d in range(DIM)])
    assert counts.min() >= 4 and counts.max() <= 12


def test_cross_entropy_moves_towards_high_objective_and_keeps_a_floor(latent_archive):
    emitter = CrossEntropyEmitter(latent_archive, batch_size=40, seed=0)
    np.testing.assert_array_equal(emitter.mean, 0.0)
    np.testing.assert_array_equal(emitter.std, 1.0)  # half the box's width
    for _ in range(10):
        batch = emitter.ask()
        emitter.tell(batch, batch[:, 0], np.zeros((len(batch), 2)), {})  # objective: the first coordinate
    assert emitter.tells == 10
    assert emitter.mean[0] > 0.5
    assert emitter.std.min() >= emitter.min_std == pytest.approx(0.05)
    assert emitter.std[0] < emitter.std[1:].mean()  # it narrows along the coordinate that matters


def test_cross_entropy_never_collapses_below_min_std(latent_archive):
    # One elite per batch: each fit has std 0, so the std falls to the floor and stays there.
    emitter = CrossEntropyEmitter(latent_archive, batch_size=4, elite_fraction=0.2, min_std=0.1, seed=1)
    for _ in range(30):
        batch = emitter.ask()
        emitter.tell(batch, -np.abs(batch).sum(axis=1), np.zeros((4, 2)), {})
    np.testing.assert_allclose(emitter.std, 0.1)
    spread = emitter.ask()
    assert spread.std(axis=0).min() > 0  # still samples around the mean, not one point


def test_cross_entropy_refits_to_the_best_share_with_smoothing(latent_archive):
    emitter = CrossEntropyEmitter(latent_archive, batch_size=10, elite_fraction=0.2, smoothing=0.7, seed=0)
    batch = np.zeros((10, DIM))
    batch[:, 0] = np.linspace(-1, 1, 10)
    objective = batch[:, 0].copy()
    objective[3] = np.nan  # ranks last
    emitter.tell(batch, objective, np.zeros((10, 2)), {})
    best = batch[[9, 8]]  # the top 2 of 10 by objective
    np.testing.assert_allclose(emitter.mean, 0.7 * best.mean(axis=0))
    expected_std = np.maximum(0.7 * best.std(axis=0) + 0.3 * 1.0, emitter.min_std)
    np.testing.assert_allclose(emitter.std, expected_std)


@pytest.mark.parametrize("kwargs, message", [
    ({"bounds": (1.0, -1.0)}, "low < high"),
    ({"bounds": (-np.inf, 1.0)}, "finite"),
    ({"bounds": (0.0,)}, "pair"),
    ({"elite_fraction": 0.0}, "elite_fraction"),
    ({"smoothing": 1.5}, "smoothing"),
    ({"min_std": 2.0}, "min_std"),
    ({"batch_size": 0}, "batch_size"),
])
def test_cross_entropy_validates_arguments(latent_archive, kwargs, message):
    with pytest.raises(ValueError, match=message):
        CrossEntropyEmitter(latent_archive, **{"batch_size": 4, **kwargs})


def test_halton_validates_arguments(latent_archive):
    with pytest.raises(ValueError, match="low < high"):
        HaltonEmitter(latent_archive, bounds=(1.0, 1.0), batch_size=4)
    with pytest.raises(ValueError, match="batch_size"):
        HaltonEmitter(latent_archive, batch_size=0)


def test_gaussian_starts_from_domain_random_solutions_then_fills_cells():
    emitter = _box_emitter("gaussian", seed=2, batch_size=16)
    assert emitter.sigma == pytest.approx(QDConfig().sigma0)
    first = emitter.ask()  # the archive is empty: the initial solutions, random ones of the domain
    np.testing.assert_array_equal(first, emitter.initial_solutions)
    assert first.shape == (16, DIM) and np.abs(first).max() > 0.6  # uniform in the box, not around the origin
    emitter.archive.add(first, *latent_predict(first)[:2], **latent_predict(first)[2])
    _run(emitter, 15)
    assert len(emitter.archive) > 40
