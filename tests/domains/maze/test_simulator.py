"""The batched simulator must be bit-identical to MiniGrid, step by step."""

import numpy as np
import pytest

from dsage_ray.domains.maze.env import MazeEnv
from dsage_ray.domains.maze.layout import load_layout
from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.simulator import TABLE_EPISODES, BatchedMazeSimulator

from .conftest import DATA, random_level


def _near_goal(level, rng):
    """The same walls with the goal moved to a reachable cell close to the start, so random
    walks reach it and termination gets exercised."""
    rows, cols = np.nonzero(level.reachable_cells)
    near = np.abs(rows - level.start[0]) + np.abs(cols - level.start[1])
    candidates = np.flatnonzero((near > 0) & (near <= 2))
    if candidates.size == 0:
        return level
    pick = int(rng.choice(candidates))
    return MazeLevel.from_bitmap(level.walls, start=level.start, goal=(int(rows[pick]), int(cols[pick])))


def _compare(level, *, see_through_walls, seed, episodes, steps, max_steps=None):
    """Steps ``episodes`` MiniGrid envs and one simulator batch with the same headings and actions.

    Actions are biased toward ``forward`` so agents actually travel (and sometimes reach the goal).
    Returns how many env steps were compared and how many episodes terminated.
    """
    rng = np.random.default_rng(seed)
    envs = [MazeEnv(level, see_through_walls=see_through_walls, max_steps=max_steps) for _ in range(episodes)]
    sim = BatchedMazeSimulator(level, see_through_walls=see_through_walls, max_steps=max_steps)
    observations = [env.reset(seed=int(rng.integers(2**31)))[0] for env in envs]
    batch = sim.reset(np.array([env.agent_dir for env in envs]))
    # Few episodes of a see-through level gather their views each step; the rest look them up in a table.
    assert (sim._views is None) == (see_through_walls and episodes < TABLE_EPISODES)
    compared, terminations = 0, 0
    running = list(range(episodes))
    for _ in range(steps):
        for k, e in enumerate(running):
            assert np.array_equal(batch["image"][k], observations[e]["image"])
            assert batch["direction"][k] == observations[e]["direction"]
            assert tuple(sim.positions[k]) == tuple(int(v) for v in envs[e].agent_pos)
        if not running:
            break
        actions = np.where(rng.random(len(running)) < 0.5, 2, rng.integers(0, 7, size=len(running)))
        batch, rewards, terminated, truncated = sim.step(actions)
        done = []
        for k, e in enumerate(running):
            obs, reward, term, trunc, _ = envs[e].step(int(actions[k]))
            observations[e] = obs
            assert rewards[k] == reward  # exact: same float64 arithmetic
            assert (terminated[k], truncated[k]) == (term, trunc)
            compared += 1
            terminations += term
            if term or trunc:
                done.append(k)
        # Finished episodes leave both batches, as in evaluate().
        alive = np.setdiff1d(np.arange(len(running)), done)
        sim.keep(alive)
        batch = {key: value[alive] for key, value in batch.items()}
        running = [running[k] for k in alive]
    return compared, terminations


@pytest.mark.parametrize("see_through_walls,episodes", [(True, 4), (False, 4), (True, 1), (False, 1)])
def test_equivalence_random_mazes(see_through_walls, episodes):
    rng = np.random.default_rng((0 if see_through_walls else 1) + 10 * episodes)
    compared = terminations = 0
    for trial in range(12 * 4 // episodes):
        level = random_level(rng, max_side=10)
        if trial % 2:
            level = _near_goal(level, rng)
        # A short step limit so truncation is exercised too.
        c, t = _compare(level, see_through_walls=see_through_walls, seed=trial, episodes=episodes, steps=80,
                        max_steps=int(rng.choice([40, level.max_steps])))
        compared += c
        terminations += t
    assert compared > 1500 and terminations > 0


def test_equivalence_labyrinth_full_length():
    level = load_layout(DATA / "labyrinth13.txt")
    for see_through_walls in (True, False):
        compared, _ = _compare(level, see_through_walls=see_through_walls, seed=7, episodes=3, steps=level.max_steps)
        assert compared == 3 * level.max_steps  # a random walk won't solve it: all episodes truncate


def test_occlusion_actually_hides_cells():
    level = load_layout(DATA / "labyrinth13.txt")
    sim_open = BatchedMazeSimulator(level, see_through_walls=True)
    sim_occluded = BatchedMazeSimulator(level, see_through_walls=False)
    directions = np.arange(4)
    seen_open = sim_open.reset(directions)["image"]
    seen_occluded = sim_occluded.reset(directions)["image"]
    assert (seen_open[..., 0] != 0).all()
    assert (seen_occluded[..., 0] == 0).any()  # unseen cells encode as (0, 0, 0)


@pytest.mark.slow
@pytest.mark.parametrize("see_through_walls", [True, False])
def test_equivalence_long(see_through_walls):
    rng = np.random.default_rng(100 + see_through_walls)
    compared = 0
    for trial in range(60):
        level = random_level(rng, max_side=16, density=float(rng.uniform(0.1, 0.5)))
        if trial % 3 == 0:
            level = _near_goal(level, rng)
        compared += _compare(level, see_through_walls=see_through_walls, seed=trial, episodes=8,
                             steps=level.max_steps)[0]
    assert compared > 50_000


def test_rejects_bad_input():
    level = load_layout(DATA / "small.txt")
    sim = BatchedMazeSimulator(level)
    sim.reset(np.zeros(3))
    with pytest.raises(ValueError, match="actions"):
        sim.step(np.array([0, 7, 1]))
    with pytest.raises(ValueError, match="expected 3"):
        sim.step(np.array([0, 1]))
    with pytest.raises(ValueError, match="directions"):
        sim.reset(np.array([4]))


def test_several_levels_step_as_each_does_alone():
    rng = np.random.default_rng(5)
    levels = []
    while len(levels) < 3:
        level = MazeLevel.from_bitmap(rng.random((7, 7)) < 0.3)
        if level.valid:
            levels.append(level)
    together = BatchedMazeSimulator(levels)
    directions = rng.integers(0, 4, size=6)
    index = np.array([0, 1, 2, 2, 1, 0])
    obs = together.reset(directions, index)
    # Every episode of the batch against a simulator of its level alone, from the same start, step by step.
    singles = [BatchedMazeSimulator(levels[j]) for j in index]
    for i, single in enumerate(singles):
        assert np.array_equal(obs["image"][i], single.reset(directions[i:i + 1])["image"][0])
    for _ in range(60):
        actions = rng.integers(0, 3, size=6)
        obs, rewards, terminated, truncated = together.step(actions)
        for i, single in enumerate(singles):
            obs_i, rewards_i, terminated_i, truncated_i = single.step(actions[i:i + 1])
            assert np.array_equal(obs["image"][i], obs_i["image"][0])
            assert (rewards[i], terminated[i], truncated[i]) == (rewards_i[0], terminated_i[0], truncated_i[0])
            assert np.array_equal(together.positions[i], single.positions[0])
    together.keep(np.array([4, 1]))
    assert together.level_index.tolist() == [1, 1]


def test_several_levels_must_share_a_size_and_an_index_must_name_one():
    small = load_layout(DATA / "small.txt")
    with pytest.raises(ValueError, match="share a size"):
        BatchedMazeSimulator([small, MazeLevel.from_bitmap(np.zeros((small.height + 1, small.width)))])
    with pytest.raises(ValueError, match="at least one level"):
        BatchedMazeSimulator([])
    sim = BatchedMazeSimulator([small, small])
    with pytest.raises(ValueError, match="level_index"):
        sim.reset(np.zeros(2), np.array([0, 2]))
