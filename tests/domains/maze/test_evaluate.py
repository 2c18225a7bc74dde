import json

import numpy as np
import pytest

from dsage_ray.domains.maze.env import minigrid_evaluate
from dsage_ray.domains.maze.evaluate import evaluate
from dsage_ray.domains.maze.layout import load_layout, parse_layout
from dsage_ray.domains.maze.level import MazeLevel

from .conftest import DATA, UniformRandomAgent

#: Small and open enough that uniformly random actions sometimes reach the goal (max 60 steps).
EASY = "S.#.\n....\n.#.G\n"


def test_matches_minigrid_reference_loop():
    level = parse_layout(EASY)
    # Only left/right/forward, so that some of the random walks reach the goal.
    result = evaluate(level, UniformRandomAgent(3), episodes=24, seed=4)
    lengths, successes, occupancy = minigrid_evaluate(level, UniformRandomAgent(3), episodes=24, seed=4)
    assert np.array_equal(result.episode_lengths, lengths)
    assert np.array_equal(result.successes, successes)
    np.testing.assert_allclose(result.occupancy, occupancy, rtol=1e-6)
    assert successes.any() and not successes.all()  # both outcomes are exercised


def test_reproducible_for_a_seed_and_varies_across_seeds():
    level = parse_layout(EASY)
    a = evaluate(level, UniformRandomAgent(3), episodes=20, seed=11)
    b = evaluate(level, UniformRandomAgent(3), episodes=20, seed=11)
    c = evaluate(level, UniformRandomAgent(3), episodes=20, seed=12)
    assert a.to_json(occupancy=True) == b.to_json(occupancy=True)
    assert not np.array_equal(a.occupancy, c.occupancy)


@pytest.mark.parametrize("layout", [EASY, (DATA / "small.txt").read_text()])
def test_occupancy_and_summary_invariants(layout):
    level = parse_layout(layout)
    agent = UniformRandomAgent(3)
    episodes = 30
    r = evaluate(level, agent, episodes=episodes, seed=0)
    assert r.occupancy.dtype == np.float32 and r.occupancy.shape == level.walls.shape
    # One visit is recorded before every step.
    assert r.occupancy.sum() * episodes == pytest.approx(r.episode_lengths.sum())
    assert r.occupancy[level.goal] == 0
    assert r.occupancy[level.start] >= 1
    assert (r.occupancy[~level.reachable_cells] == 0).all()
    failed = ~r.successes
    assert (r.episode_lengths[failed] == level.max_steps).all()
    assert (r.episode_lengths[r.successes] >= level.optimal_path_length).all()
    assert r.mean_path_length == pytest.approx(r.episode_lengths.mean())
    assert r.success_rate == pytest.approx(r.successes.mean())
    assert 0 < r.explored_fraction <= 1 and 0 <= r.repeated_visits <= level.max_steps
    # Finished episodes leave the batch: the batch never grows and ends smaller than it started.
    sizes = agent.batch_sizes
    assert sizes[0] == episodes and all(a >= b for a, b in zip(sizes, sizes[1:]))
    assert len(sizes) == r.episode_lengths.max()


def test_straight_corridor_exact_measures():
    # An agent that only moves forward, facing right: start (0,0) to goal (0,3) in 3 steps.
    class Forward(UniformRandomAgent):
        def act(self, obs, state, rng):
            return np.full(len(obs["direction"]), 2), state

    level = parse_layout("S..G\n####\n")
    # Only the episodes whose random initial heading is "right" succeed; check both kinds.
    r = evaluate(level, Forward(), episodes=8, seed=0)
    facing_right = r.successes
    assert (r.episode_lengths[facing_right] == 3).all()
    assert (r.episode_lengths[~facing_right] == level.max_steps).all()
    assert facing_right.any() and (~facing_right).any()
    n_right = facing_right.sum()
    # Right-facing episodes visit (0,0),(0,1),(0,2) once each; the others sit on the start.
    expected_start = (n_right + (8 - n_right) * level.max_steps) / 8
    assert r.occupancy[0, 0] == pytest.approx(expected_start)
    assert r.occupancy[0, 1] == pytest.approx(n_right / 8)
    assert r.explored_fraction == pytest.approx((n_right * 4 + (8 - n_right) * 1) / 8 / 4)
    assert r.repeated_visits == pytest.approx((8 - n_right) * (level.max_steps - 1) / 8)


def test_invalid_level_does_not_run_agent():
    agent = UniformRandomAgent()
    r = evaluate(MazeLevel.from_bitmap(np.ones((16, 16))), agent, episodes=50, seed=0)
    assert not r.valid and r.mean_path_length == 0 and r.episodes == 0 and agent.batch_sizes == []
    assert r.occupancy.shape == (16, 16) and not r.occupancy.any()
    json.loads(r.to_json())


def test_see_through_setting_is_passed_on():
    # The random agent ignores observations, so the outcome is the same; this checks it runs.
    level = load_layout(DATA / "small.txt")
    a = evaluate(level, UniformRandomAgent(), episodes=5, seed=1, see_through_walls=False)
    b = evaluate(level, UniformRandomAgent(), episodes=5, seed=1, see_through_walls=True)
    assert np.array_equal(a.episode_lengths, b.episode_lengths)


def test_levels_evaluated_together_match_one_at_a_time_for_one_level_and_keep_invalid_ones_apart():
    from dsage_ray.domains.maze.evaluate import evaluate_levels

    level = parse_layout(EASY)
    alone = evaluate(level, UniformRandomAgent(3), episodes=12, seed=9)
    (together,) = evaluate_levels([level], UniformRandomAgent(3), episodes=12, seed=9)
    assert together.to_json(occupancy=True) == alone.to_json(occupancy=True)

    walled = MazeLevel.from_bitmap(np.ones(level.walls.shape))
    agent = UniformRandomAgent(3)
    results = evaluate_levels([level, walled, level], agent, episodes=5, seed=2)
    assert [r.valid for r in results] == [True, False, True] and results[1].episodes == 0
    assert [r.episodes for r in results] == [5, 0, 5]
    assert agent.batch_sizes[0] == 10  # both valid levels' episodes in one policy step
    for result in (results[0], results[2]):
        assert np.isclose(result.mean_path_length, result.episode_lengths.mean())
        assert np.isclose(result.occupancy.sum(), result.episode_lengths.mean())  # a visit per step, goal never
    assert evaluate_levels([walled], None, episodes=3)[0].valid is False
