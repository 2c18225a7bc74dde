"""MDPFuzz's CartPole task as the shipped ``cartpole_initial_state`` space: the level is the initial state, a fault
is an episode that terminates before the 400-step limit, and an evaluation plays one episode."""

import numpy as np
import pytest

from dsage_ray.agents import load_agent
from dsage_ray.domains.gym.simulator import make_env, reset_env, run_episodes, signal_key
from dsage_ray.domains.gym.space import build_space, read_space_tables

#: A linear controller that balances the pole from any of the task's initial states, and one that always pushes left.
BALANCER = "def act(observation):\n    return int(observation[2] + 0.5 * observation[3] + 0.05 * observation[1] > 0)\n"
PUSHER = "def act(observation):\n    return 0\n"


@pytest.fixture
def space():
    tables, source = read_space_tables("cartpole_initial_state")
    return build_space(tables, source=source)


def agent_of(source: str, space, tmp_path):
    path = tmp_path / f"agent_{abs(hash(source))}.py"
    path.write_text(source)
    env = make_env(space, dict.fromkeys(("x", "x_dot", "theta", "theta_dot"), 0.0))
    try:
        return load_agent(f"python:{path}:act", observation_space=env.observation_space, action_space=env.action_space)
    finally:
        env.close()


def measures(space):
    return [space.measure(name).signal for name in ("x_end", "length")]


def test_the_level_is_the_first_observation(space):
    values = {"x": 0.04, "x_dot": -0.03, "theta": 0.02, "theta_dot": -0.05}
    env = make_env(space, values)
    try:
        first = reset_env(env, space, values, seed=0)
        np.testing.assert_allclose(first, [0.04, -0.03, 0.02, -0.05], rtol=1e-6)
        np.testing.assert_allclose(env.unwrapped.state, first, rtol=1e-6)
    finally:
        env.close()


def test_a_fall_before_the_limit_is_a_fault_and_lasting_it_is_not(space, tmp_path):
    values = {"x": 0.0, "x_dot": 0.0, "theta": 0.05, "theta_dot": 0.05}
    fell = run_episodes(space, agent_of(PUSHER, space, tmp_path), values, seed=0, episodes=10,
                        signals=measures(space))
    assert len(fell.returns) == 1  # deterministic = true: one episode an evaluation
    assert fell.terminated[0] and fell.returns[0] < 400 and not fell.success[0]
    lasted = run_episodes(space, agent_of(BALANCER, space, tmp_path), values, seed=0, episodes=1,
                          signals=measures(space))
    assert lasted.returns[0] == 400 and not lasted.terminated[0] and lasted.success[0]
    # The measures tell an early fall from a whole episode.
    length = signal_key(space.measure("length").signal)
    assert fell.signals[length][0] < 50 < lasted.signals[length][0] == 400


def test_an_episode_is_a_function_of_the_level(space, tmp_path):
    agent = agent_of(BALANCER, space, tmp_path)
    values = {"x": -0.05, "x_dot": 0.05, "theta": -0.05, "theta_dot": 0.05}
    first, again = (run_episodes(space, agent, values, seed=seed, episodes=1, signals=measures(space))
                    for seed in (0, 7))
    assert first.returns.tolist() == again.returns.tolist()
    assert {key: value.tolist() for key, value in first.signals.items()} == \
           {key: value.tolist() for key, value in again.signals.items()}
