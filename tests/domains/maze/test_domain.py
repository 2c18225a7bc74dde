import pickle

import numpy as np
import pytest

import dsage_ray.agents
import dsage_ray.domains.maze.agents
from dsage_ray.domains.maze.domain import MazeDomain
from dsage_ray.domains.maze.plugin import MazeConfig
from dsage_ray.types import AuditableDomain, Domain

from .conftest import UniformRandomAgent


@pytest.fixture
def loads(monkeypatch):
    """Replaces the agent loader with one that counts calls and returns a test agent."""
    calls = []

    def fake_load_agent(spec):
        calls.append(spec)
        return UniformRandomAgent(3)

    monkeypatch.setattr(dsage_ray.domains.maze.agents, "load_maze_agent", fake_load_agent, raising=False)
    return calls


def test_protocol_attributes():
    domain = MazeDomain(config=MazeConfig())
    assert isinstance(domain, Domain) and isinstance(domain, AuditableDomain)
    assert domain.solution_dim == 256 and domain.occupancy_shape == (16, 16) and domain.encoding_channels == 5
    assert domain.measure_names == ("num_walls", "mean_path_length")
    assert domain.measure_ranges == ((0.0, 256.0), (0.0, 648.0))
    assert domain.archive_dims == (256, 162)
    custom = MazeDomain(config=MazeConfig(height=4, width=6, measures=("explored_fraction", "num_walls"),
                                          archive_dims=(10, 0), measure_ranges=()))
    assert custom.measure_ranges == ((0.0, 1.0), (0.0, 24.0)) and custom.archive_dims == (10, 24)


def test_random_solutions_and_encode():
    domain = MazeDomain(config=MazeConfig(height=5, width=4))
    solutions = domain.random_solutions(7, np.random.default_rng(0))
    assert solutions.shape == (7, 20) and solutions.dtype == domain.solution_dtype
    assert set(np.unique(solutions)) == {0, 1}
    assert domain.encode(solutions).shape == (7, 5, 5, 4)
    assert domain.render(solutions[0], np.ones((5, 4)))[:4] == b"\x89PNG"


def test_evaluate_loads_agent_once_and_is_deterministic(loads):
    domain = MazeDomain(config=MazeConfig(height=3, width=4, episodes=10, agent="builtin:random"))
    solution = np.array([0, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0], dtype=np.float64)
    a = domain.evaluate(solution, seed=3)
    b = domain.evaluate(solution, seed=3)
    assert loads == ["builtin:random"]
    assert a.objective == 1.0 and not a.failed
    assert a.measures.tolist() == [2.0, a.info["mean_path_length"]] == b.measures.tolist()
    assert a.occupancy.shape == (3, 4) and np.array_equal(a.occupancy, b.occupancy)
    assert {"success_rate", "episode_lengths", "successes", "optimal_path_length", "start", "goal",
            "valid"} <= set(a.info)
    assert len(a.info["episode_lengths"]) == 10
    # Its work: every step of every episode.
    assert domain.work_names == ("steps",)
    assert domain.work_counts(a) == {"steps": float(sum(a.info["episode_lengths"]))} == domain.work_counts(b)


def test_invalid_solution_scores_zero_without_loading_agent(loads):
    domain = MazeDomain(config=MazeConfig(height=4, width=4))
    result = domain.evaluate(np.ones(16), seed=0)
    assert result.objective == 0.0 and result.measures.tolist() == [16.0, 0.0]
    assert loads == [] and result.info["valid"] is False
    assert domain.work_counts(result) == {"steps": 0.0}


def test_other_objectives(loads):
    level = np.zeros(12)
    for objective in ("failure_rate", "regret"):
        domain = MazeDomain(config=MazeConfig(height=3, width=4, episodes=5, objective=objective))
        assert 0.0 <= domain.evaluate(level, seed=0).objective <= 1.0


def test_pickles_without_agent(loads):
    domain = MazeDomain(config=MazeConfig(height=3, width=4, episodes=2))
    domain.evaluate(np.zeros(12), seed=0)
    clone = pickle.loads(pickle.dumps(domain))
    assert clone._agent is None and clone.config == domain.config


def test_screen_is_a_cheap_evaluation_with_fewer_episodes_of_many_levels_at_once(loads):
    domain = MazeDomain(config=MazeConfig(height=3, width=4, episodes=10))
    open_level = np.zeros(12)
    walled = np.ones(12)
    results = domain.screen(np.stack([open_level, walled, open_level]), episodes=2, seed=7)
    assert [len(r.info["episode_lengths"]) if r.info["valid"] else 0 for r in results] == [2, 0, 2]
    assert [r.objective for r in results] == [1.0, 0.0, 1.0]
    assert results[1].measures.tolist() == [12.0, 0.0]
    # One level screened alone is exactly a 2-episode evaluation with that seed.
    (alone,) = domain.screen(open_level[None], episodes=2, seed=7)
    short = MazeDomain(config=MazeConfig(height=3, width=4, episodes=2)).evaluate(open_level, seed=7)
    assert alone.measures.tolist() == short.measures.tolist()
    assert alone.info["episode_lengths"] == short.info["episode_lengths"]
    assert len(loads) == 2  # once per domain object, however many levels it screens


class _ReducingAgent(UniformRandomAgent):
    """A test agent whose reduced-precision copy is another object, counted."""

    copies = 0

    def reduced_precision(self):
        type(self).copies += 1
        copy = UniformRandomAgent(3)
        copy.spec = "test:reduced"
        return copy


def test_screen_precision_plays_the_reduced_copy_made_once(monkeypatch):
    monkeypatch.setattr(dsage_ray.domains.maze.agents, "load_maze_agent", lambda spec: _ReducingAgent(3), raising=False)
    domain = MazeDomain(config=MazeConfig(height=3, width=4, episodes=10))
    levels = np.zeros((3, 12))
    domain.screen(levels, episodes=1, seed=0, precision="bf16")
    domain.screen(levels, episodes=1, seed=1, precision="bf16")
    assert _ReducingAgent.copies == 1
    assert domain._reduced_agents["agent"].spec == "test:reduced" and domain.agent.batch_sizes == []
    domain.screen(levels, episodes=1, seed=2, precision="fp32")
    assert domain.agent.batch_sizes  # fp32 plays the agent itself
    assert pickle.loads(pickle.dumps(domain))._reduced_agents == {}
    with pytest.raises(ValueError, match="'fp32' or 'bf16'"):
        domain.screen(levels, episodes=1, seed=0, precision="auto")


def test_an_agent_without_a_reduced_copy_screens_as_it_is(loads):
    domain = MazeDomain(config=MazeConfig(height=3, width=4, episodes=10))
    levels = np.stack([np.zeros(12), np.eye(3, 4).ravel()])
    full = domain.screen(levels, episodes=2, seed=4, precision="fp32")
    reduced = domain.screen(levels, episodes=2, seed=4, precision="bf16")
    assert [r.measures.tolist() for r in full] == [r.measures.tolist() for r in reduced]


def test_the_nominal_level_is_an_open_room_scored_with_minigrids_reward():
    from dsage_ray.domains.maze.agents.builtin import WallFollowerAgent
    from dsage_ray.types import NominalDomain

    domain = MazeDomain(config=MazeConfig(height=6, width=5, agent="builtin:wall_follower"))
    assert isinstance(domain, NominalDomain)
    played = domain.play_nominal(seed=3)
    assert played.level == "an open 6x5 room (start (0, 0), goal (5, 4))" and played.return_name == "MiniGrid reward"
    assert played.success_rate == 1.0 and played.episodes == 50 and played.expected_return is None
    # MiniGrid's reward, 1 - 0.9 steps / max_steps, over the same episodes as an evaluation of the open room plays.
    from dsage_ray.domains.maze.evaluate import evaluate
    from dsage_ray.domains.maze.level import MazeLevel

    run = evaluate(MazeLevel.from_bitmap(np.zeros((6, 5))), WallFollowerAgent(), episodes=50, seed=3)
    rewards = 1.0 - 0.9 * run.episode_lengths / run.max_steps
    assert played.mean_return == pytest.approx(rewards.mean())
    assert played.return_std == pytest.approx(rewards.std(ddof=1))
    assert domain.play_nominal(seed=3) == played and domain.play_nominal(seed=4) != played


def test_an_agent_that_never_reaches_the_goal_scores_nothing_in_the_open_room(monkeypatch):
    from .conftest import UniformRandomAgent

    class Spinner(UniformRandomAgent):
        def act(self, obs, state, rng):
            return np.zeros(len(state), dtype=np.int64), state  # turns left for ever

    monkeypatch.setattr(dsage_ray.domains.maze.agents, "load_maze_agent", lambda spec: Spinner(), raising=False)
    played = MazeDomain(config=MazeConfig(height=4, width=4)).play_nominal(seed=0)
    assert (played.success_rate, played.mean_return, played.return_std) == (0.0, 0.0, 0.0)
    assert "see_through_walls = true" in played.causes
