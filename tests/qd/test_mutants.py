import numpy as np
import pytest

from dsage_ray.config import QDConfig
from dsage_ray.qd.mutants import best_elites, elite_mutants
from tests.qd.helpers import DIM, bitmap_predict, latent_predict


def _add(archive, solutions, objective):
    _, measures, extra = bitmap_predict(solutions)
    archive.add(solutions, np.asarray(objective, dtype=np.float64), measures, **extra)


def _distinct_bitmaps(n):
    # Distinct wall counts put every bitmap in its own cell.
    return np.array([[1] * k + [0] * (DIM - k) for k in range(n)], dtype=np.int8)


def test_best_elites_takes_the_share_and_every_tie_with_its_last_member(bitmap_archive):
    _add(bitmap_archive, _distinct_bitmaps(10), [1.0, 1.0, 1.0, 0.9, 0.5, 0.5, 0.2, 0.1, 0.0, 0.0])
    objective = bitmap_archive.data("objective")
    assert sorted(objective[best_elites(bitmap_archive, share=0.1)]) == [1.0, 1.0, 1.0]  # 1 taken, 2 tied with it
    assert sorted(objective[best_elites(bitmap_archive, share=0.4)]) == [0.9, 1.0, 1.0, 1.0]
    assert len(best_elites(bitmap_archive, share=0.5)) == 6  # 0.5 tied: both taken
    assert len(best_elites(bitmap_archive, share=1.0)) == 10


def test_bitmap_mutants_are_within_mutation_cells_of_a_best_elite_only(bitmap_archive):
    bitmaps = _distinct_bitmaps(12)
    _add(bitmap_archive, bitmaps, [1.0, 1.0] + [0.3] * 10)
    best = bitmaps[:2]
    qd = QDConfig(emitter="map_elites", mutation_cells=2)
    mutants = elite_mutants(bitmap_archive, count=200, share=0.1, qd=qd, rng=np.random.default_rng(0))
    assert mutants.shape == (200, DIM) and mutants.dtype == np.int8 and set(np.unique(mutants)) <= {0, 1}
    distance_to_best = np.abs(mutants[:, None, :] - best[None]).sum(axis=2).min(axis=1)
    assert distance_to_best.max() <= 2 and distance_to_best.max() > 0
    # Both parents are drawn: some mutants are nearer the one, some nearer the other.
    nearer_first = np.abs(mutants - best[0]).sum(axis=1) < np.abs(mutants - best[1]).sum(axis=1)
    assert 0 < nearer_first.sum() < 200


def test_latent_mutants_add_gaussian_noise_of_sigma0(latent_archive):
    parent = np.full((1, latent_archive.solution_dim), 0.25)
    objective, measures, extra = latent_predict(parent)
    latent_archive.add(parent, objective, measures, **extra)
    mutants = elite_mutants(latent_archive, count=4000, share=1.0, qd=QDConfig(emitter="cma_me", sigma0=0.3),
                            rng=np.random.default_rng(1))
    noise = mutants - parent
    assert abs(noise.mean()) < 0.01 and noise.std() == pytest.approx(0.3, rel=0.02)


def test_no_mutant_of_an_empty_archive_and_none_without_an_operator(bitmap_archive):
    rng = np.random.default_rng(0)
    assert elite_mutants(bitmap_archive, count=5, share=0.1, qd=QDConfig(), rng=rng).shape == (0, DIM)
    _add(bitmap_archive, _distinct_bitmaps(3), [1.0, 0.5, 0.0])
    with pytest.raises(ValueError, match="'random' has no mutation"):
        elite_mutants(bitmap_archive, count=5, share=0.1, qd=QDConfig(emitter="random"), rng=rng)


@pytest.mark.parametrize("emitter", ["gaussian", "halton", "cross_entropy"])
def test_box_emitters_mutate_with_gaussian_noise_clipped_to_the_bounds(latent_archive, emitter):
    parent = np.full((1, latent_archive.solution_dim), 0.9)
    latent_archive.add(parent, *latent_predict(parent)[:2], **latent_predict(parent)[2])
    qd = QDConfig(emitter=emitter, sigma0=0.3)
    free = elite_mutants(latent_archive, count=500, share=1.0, qd=qd, rng=np.random.default_rng(1))
    clipped = elite_mutants(latent_archive, count=500, share=1.0, qd=qd, rng=np.random.default_rng(1),
                            bounds=(-1.0, 1.0))
    assert free.max() > 1.0 and clipped.max() == 1.0
    np.testing.assert_array_equal(clipped, np.clip(free, -1.0, 1.0))


def test_evaluated_parents_are_every_level_as_good_as_the_best_elites(bitmap_archive):
    bitmaps = _distinct_bitmaps(4)
    _add(bitmap_archive, bitmaps, [1.0, 1.0, 0.2, 0.0])
    # Evaluated: the two elites, five more levels as good as them near the first (one wall apart; the archive kept
    # one of each cell), and a level worse than them that must never parent.
    crowd = np.repeat(bitmaps[1:2], 5, axis=0)
    evaluated = (np.concatenate([bitmaps, crowd]), np.array([1.0, 1.0, 0.2, 0.0] + [1.0] * 5))
    qd = QDConfig(emitter="map_elites", mutation_cells=1)
    rng = np.random.default_rng(0)
    mutants = elite_mutants(bitmap_archive, count=700, share=0.1, qd=qd, rng=rng, evaluated=evaluated)
    nearest = np.abs(mutants[:, None, :] - bitmaps[None]).sum(axis=2).argmin(axis=1)
    # Parents: levels 0 and 1 of the elites, level 1 six times in seven draws (its evaluations are six of seven).
    assert set(nearest) <= {0, 1, 2} and (nearest == 1).mean() > 0.75
    from_elites = elite_mutants(bitmap_archive, count=700, share=0.1, qd=qd, rng=np.random.default_rng(0))
    nearest = np.abs(from_elites[:, None, :] - bitmaps[None]).sum(axis=2).argmin(axis=1)
    assert 0.35 < (nearest == 1).mean() < 0.65  # one elite a cell: an even draw


def test_evaluated_parents_fall_back_to_the_elites_when_none_was_recorded(bitmap_archive):
    _add(bitmap_archive, _distinct_bitmaps(2), [1.0, 0.0])
    empty = (np.empty((0, DIM), dtype=np.int8), np.empty(0))
    mutants = elite_mutants(bitmap_archive, count=10, share=0.5, qd=QDConfig(emitter="map_elites"),
                            rng=np.random.default_rng(0), evaluated=empty)
    assert mutants.shape == (10, DIM)
