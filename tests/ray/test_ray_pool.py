"""The simulator pool: order, equivalence with in-process evaluation, faults, resources, threads.

Starting actor processes is the slow part on a loaded 2-core machine, so one pool is shared by
the module and tests check counter deltas.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import ray

from dsage_ray.core.evaluation import InProcessEvaluator
from dsage_ray.core.runner import DSAGE
from dsage_ray.ray.pool import PoolResourceError, SimulatorPool
from tests.fakes import BitmapDomain
from tests.ray.helpers import RAISING_SEED, SlowBitmapDomain, archive_snapshot, bitmap_domain, slow_bitmap_domain, small_config


@pytest.fixture(scope="module")
def pool(ray_session):
    with SimulatorPool(config=small_config(), num_workers=2, cpus_per_worker=0.5,
                       domain_factory=slow_bitmap_domain) as pool:
        yield pool


@pytest.fixture(scope="module")
def batch():
    solutions = BitmapDomain().random_solutions(40, np.random.default_rng(1))
    seeds = [1000 + i for i in range(len(solutions))]
    seeds[4] = RAISING_SEED
    return solutions, seeds, InProcessEvaluator(domain=SlowBitmapDomain(base_s=0, extra_s=0))(solutions, seeds)


def same_results(a, b) -> bool:
    return len(a) == len(b) and all(
        x.objective == y.objective and np.array_equal(x.measures, y.measures)
        and np.array_equal(x.occupancy, y.occupancy) and x.failed == y.failed and x.info == y.info
        for x, y in zip(a, b))


@pytest.mark.parametrize("chunk_size", [1, 3])
def test_results_in_submission_order_and_equal_to_in_process(pool, batch, chunk_size, monkeypatch):
    solutions, seeds, expected = batch
    monkeypatch.setattr(pool, "chunk_size", chunk_size)
    evaluations, deaths = pool.stats.evaluations, pool.stats.actor_deaths
    results = pool(solutions, seeds)
    assert [r.info.get("seed") for r in results if not r.failed] == [s for s, r in zip(seeds, expected)
                                                                      if not r.failed]
    assert same_results(results, expected)
    assert pool.stats.evaluations - evaluations == len(solutions)
    assert pool.stats.actor_deaths == deaths


def test_an_evaluation_that_raises_is_a_failed_result_not_a_dead_actor(pool, batch):
    solutions, seeds, _ = batch
    deaths, failed = pool.stats.actor_deaths, pool.stats.failed_evaluations
    results = pool(solutions[:8], seeds[:8])
    assert results[4].failed and "injected failure" in results[4].error
    assert [r.failed for r in results].count(True) == 1
    assert pool.stats.actor_deaths == deaths
    assert pool.stats.failed_evaluations - failed == 1


def test_thread_limits_are_set_per_actor(pool):
    assert [info["omp_num_threads"] for info in pool.actor_info] == ["1", "1"]
    assert len({info["pid"] for info in pool.actor_info}) == 2


def test_killed_actor_is_replaced_and_nothing_is_lost_or_duplicated(pool, batch):
    solutions, seeds, expected = batch
    evaluations, deaths = pool.stats.evaluations, pool.stats.actor_deaths
    victim = pool.actor_handles()[0]
    killer = threading.Timer(0.25, lambda: ray.kill(victim))
    killer.start()
    started = time.perf_counter()
    results = pool(solutions, seeds)
    killer.join()
    assert time.perf_counter() - started > 0.25, "the batch finished before the kill: the test proves nothing"
    assert pool.stats.actor_deaths - deaths == 1
    assert pool.stats.resubmitted_chunks >= 1
    assert pool.stats.evaluations - evaluations == len(solutions)  # each solution accepted exactly once
    assert same_results(results, expected)
    # The replacement serves the next batch.
    assert same_results(pool(solutions[:6], seeds[:6]), expected[:6])


@pytest.mark.parametrize("overrides", [{"variant": "map_elites", "budget": 160},
                                       # the batch is out in a background thread while the surrogate trains
                                       {"variant": "dsage", "budget": 90, "pipeline": True}],
                         ids=["map_elites", "dsage_pipelined"])
def test_killed_actor_during_a_run_leaves_the_archive_unchanged(pool, overrides):
    config = small_config(**overrides)
    uninterrupted = DSAGE(config=config, domain=SlowBitmapDomain(base_s=0, extra_s=0))
    uninterrupted.run()
    deaths = pool.stats.actor_deaths
    runner = DSAGE(config=config, evaluator=pool, domain=BitmapDomain())
    runner.step()
    runner.step()
    killer = threading.Timer(0.05, lambda: ray.kill(pool.actor_handles()[1]))
    killer.start()
    runner.run()
    killer.join()
    assert pool.stats.actor_deaths - deaths == 1
    assert runner.evals == uninterrupted.evals == config.budget
    assert archive_snapshot(runner.archive) == archive_snapshot(uninterrupted.archive)
    if config.pipeline:
        assert any(row.get("time_overlapped", 0) > 0 for row in runner.history)


def test_more_simulators_than_the_cluster_has_fails_at_once(ray_session):
    started = time.perf_counter()
    with pytest.raises(PoolResourceError, match="ray.num_workers"):
        SimulatorPool(config=small_config(), num_workers=5, cpus_per_worker=1.0, domain_factory=bitmap_domain)
    assert time.perf_counter() - started < 5


def test_simulators_that_cannot_be_placed_time_out_with_a_clear_message(pool):
    # The shared pool holds 1 of the 2 CPUs: 1.5 more fit the cluster on paper but never start.
    with pytest.raises(PoolResourceError, match="started within 2s"):
        SimulatorPool(config=small_config(), num_workers=1, cpus_per_worker=1.5, domain_factory=bitmap_domain,
                      placement_timeout_s=2.0)


def test_a_deadline_stops_handing_out_work_and_returns_the_prefix_in_order(pool, batch, monkeypatch):
    solutions, seeds, expected = batch
    monkeypatch.setattr(pool, "chunk_size", 3)
    counts: list[int] = []
    results = pool.evaluate_until(solutions, seeds, deadline=time.perf_counter() - 1.0, progress=counts.append)
    # The first hand-out (max_in_flight chunks per actor) still runs: a batch always makes progress.
    assert len(results) == 2 * pool.max_in_flight * 3
    assert same_results(results, expected[:len(results)])
    assert counts == sorted(counts) and counts[-1] == len(results)


def test_a_deadline_still_reruns_the_chunks_of_an_actor_that_died(pool, batch, monkeypatch):
    solutions, seeds, expected = batch
    monkeypatch.setattr(pool, "chunk_size", 2)
    deaths = pool.stats.actor_deaths
    killer = threading.Timer(0.1, lambda: ray.kill(pool.actor_handles()[0]))
    killer.start()
    results = pool.evaluate_until(solutions, seeds, deadline=time.perf_counter() + 0.3)
    killer.join()
    assert pool.stats.actor_deaths - deaths == 1
    assert 0 < len(results) < len(solutions)
    assert same_results(results, expected[:len(results)])  # a prefix without a hole
