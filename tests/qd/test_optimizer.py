import numpy as np
import pytest
from ribs.emitters import EvolutionStrategyEmitter, GaussianEmitter

from dsage_ray.config import QDConfig
from dsage_ray.qd import (
    CrossEntropyEmitter,
    HaltonEmitter,
    MapElitesBitmapEmitter,
    RandomEmitter,
    archive_stats,
    emitter_seeds,
    make_scheduler,
    run_inner_loop,
)
from tests.qd.helpers import (DIM, bitmap_predict, bitmap_sampler, box_sampler, checkpoint_round_trip, latent_predict,
                              make_bitmap_archive, make_latent_archive)

KINDS = {
    "map_elites": (MapElitesBitmapEmitter, make_bitmap_archive, bitmap_predict, bitmap_sampler),
    "cma_me": (EvolutionStrategyEmitter, make_latent_archive, latent_predict, bitmap_sampler),
    "random": (RandomEmitter, make_bitmap_archive, bitmap_predict, bitmap_sampler),
    "gaussian": (GaussianEmitter, make_latent_archive, latent_predict, box_sampler),
    "halton": (HaltonEmitter, make_latent_archive, latent_predict, box_sampler),
    "cross_entropy": (CrossEntropyEmitter, make_latent_archive, latent_predict, box_sampler),
}


def _scheduler(kind, seed=0, archive_seed=3):
    cls, make, predict, sampler = KINDS[kind]
    config = QDConfig(emitter=kind, num_emitters=3, batch_size=4, mutation_cells=2)
    archive = make(seed=archive_seed)
    return make_scheduler(archive, config=config, solution_dim=DIM, random_solutions=sampler, seed=seed), predict


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_scheduler_ask_tell_fills_archive(kind):
    scheduler, predict = _scheduler(kind)
    assert len(scheduler.emitters) == 3
    assert all(type(e) is KINDS[kind][0] for e in scheduler.emitters)
    ticks = []
    timings = run_inner_loop(scheduler, predict, iterations=6, progress=ticks.append)
    assert ticks == [1] * 6
    assert timings.iterations == 6 and timings.solutions == 6 * 3 * 4
    assert timings.ask_s > 0 and timings.tell_s > 0 and timings.overhead_ms_per_iteration > 0
    stats = archive_stats(scheduler.archive)
    assert stats["num_elites"] > 1
    assert stats["num_elites"] == len(scheduler.archive)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_scheduler_is_deterministic_and_seed_dependent(kind):
    def asks(seed):
        scheduler, predict = _scheduler(kind, seed=seed)
        run_inner_loop(scheduler, predict, iterations=4)
        return scheduler.ask()

    np.testing.assert_array_equal(asks(1), asks(1))
    assert not np.array_equal(asks(1), asks(2))


def test_emitters_get_distinct_seeds():
    scheduler, _ = _scheduler("random", seed=0)
    first = [e.ask() for e in scheduler.emitters]
    assert not np.array_equal(first[0], first[1])
    seeds = emitter_seeds(0, 5)
    assert len(set(seeds)) == 5 and seeds == emitter_seeds(0, 5)
    assert emitter_seeds(None, 2) == [None, None]


def test_cma_me_settings():
    config = QDConfig(emitter="cma_me", num_emitters=1, batch_size=7, sigma0=0.3)
    scheduler = make_scheduler(make_latent_archive(), config=config, solution_dim=DIM,
                               random_solutions=bitmap_sampler, seed=0)
    (emitter,) = scheduler.emitters
    np.testing.assert_array_equal(emitter.x0, np.zeros(DIM))
    assert emitter.batch_size == 7
    assert scheduler.ask().shape == (7, DIM)


def test_cma_me_stays_unbounded_in_a_box_the_domain_clips_to():
    config = QDConfig(emitter="cma_me", num_emitters=1, batch_size=20, sigma0=0.2)
    scheduler = make_scheduler(make_latent_archive(), config=config, solution_dim=DIM,
                               random_solutions=bitmap_sampler, seed=0, bounds=(-0.5, 0.5))
    assert np.isinf(scheduler.emitters[0].upper_bounds).all()  # pyribs would redraw out-of-box samples for ever


@pytest.mark.parametrize("kind", ["gaussian", "halton", "cross_entropy"])
def test_box_emitters_search_the_domain_bounds_else_the_unit_box(kind):
    config = QDConfig(emitter=kind, num_emitters=2, batch_size=5)
    for bounds, expected in [(None, (-1.0, 1.0)), ((0.0, 2.0), (0.0, 2.0))]:
        scheduler = make_scheduler(make_latent_archive(), config=config, solution_dim=DIM, random_solutions=box_sampler,
                                   seed=0, bounds=bounds)
        for emitter in scheduler.emitters:
            np.testing.assert_array_equal(emitter.lower_bounds, expected[0])
            np.testing.assert_array_equal(emitter.upper_bounds, expected[1])
        batch = scheduler.ask()
        assert batch.shape == (10, DIM) and batch.min() >= expected[0] and batch.max() <= expected[1]


def test_make_scheduler_rejects_bad_input():
    with pytest.raises(ValueError, match="unknown emitter"):
        make_scheduler(make_bitmap_archive(), config=QDConfig(emitter="nope"), solution_dim=DIM,
                       random_solutions=bitmap_sampler, seed=0)
    with pytest.raises(ValueError, match="solution_dim"):
        make_scheduler(make_bitmap_archive(), config=QDConfig(), solution_dim=DIM + 1,
                       random_solutions=bitmap_sampler, seed=0)
    with pytest.raises(ValueError, match="low < high"):
        make_scheduler(make_latent_archive(), config=QDConfig(emitter="halton"), solution_dim=DIM,
                       random_solutions=box_sampler, seed=0, bounds=(1.0, -1.0))


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_state_round_trip_gives_identical_subsequent_asks(kind, tmp_path):
    scheduler, predict = _scheduler(kind)
    # Past the initial random batches and, for CMA-ME, long enough for restarts (which draw from the
    # archive's RNG) to happen.
    run_inner_loop(scheduler, predict, iterations=30)
    restored = checkpoint_round_trip(scheduler, tmp_path)
    if kind == "random":  # the sampler is code: a checkpoint leaves it out and the run attaches it again
        with pytest.raises(RuntimeError, match="without its sampler"):
            restored.emitters[0].ask()
        for emitter in restored.emitters:
            emitter.attach(KINDS[kind][3])
    # The restored emitters share the restored archive, not a copy each.
    assert all(e.archive is restored.archive for e in restored.emitters)
    assert restored.archive is not scheduler.archive
    for _ in range(30):
        a, b = scheduler.ask(), restored.ask()
        np.testing.assert_array_equal(a, b)
        scheduler.tell(*predict(a)[:2], **predict(a)[2])
        restored.tell(*predict(b)[:2], **predict(b)[2])
    assert archive_stats(scheduler.archive) == archive_stats(restored.archive)
    if kind == "cma_me":
        assert sum(e.restarts for e in scheduler.emitters) > 0


def _cma_es_signatures() -> dict[str, set[str]]:
    """The types each of pyribs' compiled CMA-ES functions has been compiled for in this process."""
    import numba
    from ribs.emitters.opt._cma_es import CMAEvolutionStrategy

    functions = {name: getattr(CMAEvolutionStrategy, name) for name in dir(CMAEvolutionStrategy)}
    return {name: {str(s) for s in function.signatures} for name, function in functions.items()
            if isinstance(function, numba.core.registry.CPUDispatcher)}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_after_compile_emitters_an_inner_loop_of_that_solution_type_compiles_nothing_more(dtype):
    from ribs.archives import GridArchive

    from dsage_ray.qd.optimizer import compile_emitters

    config = QDConfig(emitter="cma_me", num_emitters=2, batch_size=6, sigma0=0.2)
    compile_emitters(config=config, solution_dim=DIM, solution_dtype=dtype, random_solutions=box_sampler)
    assert not compile_emitters(config=config, solution_dim=DIM, solution_dtype=dtype, random_solutions=box_sampler)
    compiled = _cma_es_signatures()
    assert compiled and all(compiled.values())
    archive = GridArchive(solution_dim=DIM, dims=(16, 8), ranges=[(0, 16), (0, 8)], seed=1, solution_dtype=dtype)
    scheduler = make_scheduler(archive, config=config, solution_dim=DIM, random_solutions=box_sampler, seed=1)
    run_inner_loop(scheduler, lambda x: latent_predict(x)[:2] + ({},), 30)
    assert _cma_es_signatures() == compiled


def test_compile_emitters_leaves_emitters_without_compiled_code_alone():
    from dsage_ray.qd.optimizer import compile_emitters

    config = QDConfig(emitter="gaussian", num_emitters=1, batch_size=4)
    assert not compile_emitters(config=config, solution_dim=DIM, solution_dtype=np.float32, random_solutions=box_sampler)
