"""The collection re-evaluation and ``compare`` on the Ray simulator pool: a dying simulator loses no level."""

from __future__ import annotations

import functools
import os

import numpy as np
import pytest

from dsage_ray.audit import compare as compare_module
from dsage_ray.audit.collection import audit_config, build_collection
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.audit.compare import compare_agents
from dsage_ray.cli import main
from dsage_ray.domains import build_domain
from dsage_ray.domains.maze.domain import MazeDomain
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.qd.archives import make_archive
from dsage_ray.ray.pool import SimulatorPool

#: The wall follower: its episodes end at the goal, where the random agent's run to the step limit.
AUDITED = "builtin:wall_follower"
#: The other agent of ``compare``.
OTHER = "builtin:random"


class DyingMazeDomain(MazeDomain):
    """Kills its own process on the first evaluation of the whole test (a marker file makes it once)."""

    def __init__(self, *, config, marker: str):
        super().__init__(config=config)
        self.marker = marker

    def evaluate(self, solution, seed):
        try:
            os.close(os.open(self.marker, os.O_CREAT | os.O_EXCL))
        except FileExistsError:
            return super().evaluate(solution, seed)
        os._exit(1)  # a hard crash: no exception, the actor is simply gone


def dying_domain(config, *, marker: str) -> DyingMazeDomain:
    return DyingMazeDomain(config=config.maze, marker=marker)


@pytest.fixture(scope="module")
def search(tmp_path_factory):
    """A small "search archive" of 6 valid levels and the audit config that goes with it."""
    config = audit_config(agent=AUDITED, preset="tiny", seed=7, overrides={"maze.episodes": 4, "ray.num_workers": 2})
    domain = build_domain(config)
    levels = random_valid_levels(6, seed=1)
    archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges,
                           solution_dtype=domain.solution_dtype)
    archive.add(np.array([level.walls.ravel() for level in levels], dtype=np.int8), np.full(len(levels), 0.5),
                np.array([[level.num_walls, level.optimal_path_length] for level in levels], dtype=float))
    return config, archive, tmp_path_factory.mktemp("ray_audit")


def test_a_dying_simulator_loses_no_level(ray_session, search):
    config, archive, folder = search
    in_process = build_collection(archive, config=config, out_dir=folder / "in_process")
    pool = SimulatorPool(config=config, chunk_size=1,
                         domain_factory=functools.partial(dying_domain, marker=str(folder / "died")))
    try:
        on_pool = build_collection(archive, config=config, out_dir=folder / "on_pool", evaluator=pool)
    finally:
        pool.close()
    assert (folder / "died").exists() and pool.stats.actor_deaths >= 1, "no simulator died: the test proves nothing"
    expected, got = load_collection(in_process), load_collection(on_pool)
    assert got["failed_reevaluations"] == 0 and len(got["levels"]) == len(archive) == len(expected["levels"])
    keys = ("level_file", "seed", "objective", "success_rate", "episode_lengths", "measures")
    assert [{k: lv[k] for k in keys} for lv in got["levels"]] == [{k: lv[k] for k in keys} for lv in expected["levels"]]


def test_compare_on_the_pool_equals_in_process(ray_session, search, capsys, monkeypatch):
    config, archive, folder = search
    collection = folder / "in_process"
    if not collection.exists():
        build_collection(archive, config=config, out_dir=collection)
    serial = compare_agents(AUDITED, OTHER, collection_dir=collection)
    # The command's own comparison is the pooled one: one pool start, not two (each costs seconds).
    pooled_runs = []

    def recording(*args, **kwargs):
        pooled_runs.append(compare_agents(*args, **kwargs))
        return pooled_runs[-1]

    monkeypatch.setattr(compare_module, "compare_agents", recording)
    html = folder / "compare.html"
    assert main(["compare", "--agent", AUDITED, "--agent", OTHER, "--collection", str(collection),
                 "--workers", "2", "--html", str(html)]) == 0
    (pooled,) = pooled_runs
    assert pooled["levels"] == serial["levels"] and pooled["summary"] == serial["summary"]
    recorded = {lv["id"]: lv["success_rate"] for lv in load_collection(collection)["levels"]}
    assert {r["id"]: r["success_a"] for r in pooled["levels"]} == recorded
    captured = capsys.readouterr()
    assert f"{len(recorded)} levels; mean success A" in captured.out and html.is_file()
    assert "comparing" in captured.err  # the progress bar
