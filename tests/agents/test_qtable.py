"""``qtable:PATH.npy``: a table of action values, played greedily, read as data and checked against the spaces."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

from dsage_ray.agents import load_agent
from dsage_ray.agents.base import AgentError

TAXI = gym.make("Taxi-v3")


def load(spec: str, env: gym.Env = TAXI):
    return load_agent(spec, observation_space=env.observation_space, action_space=env.action_space)


def test_it_takes_each_state_s_best_action_ties_to_the_lowest(tmp_path):
    table = np.random.default_rng(0).normal(size=(500, 6))
    table[7] = 1.0  # a tie: action 0
    np.save(tmp_path / "q.npy", table)
    agent = load(f"qtable:{tmp_path / 'q.npy'}")
    states = np.array([0, 7, 499, 42], dtype=np.int64)
    actions, state = agent.act(states, agent.initial_state(4), np.random.default_rng(1))
    assert actions.dtype == np.int64 and actions.tolist() == [int(np.argmax(table[s])) for s in states]
    assert actions[1] == 0 and state is None


@pytest.mark.parametrize("content, message", [
    (np.zeros((500, 5)), "its shape (500, 5) is not the environment's (states, actions) (500, 6)"),
    (np.zeros(500), "expected a (states, actions) array of action values, got shape (500,)"),
    (np.array([["a"] * 6] * 500), "got shape (500, 6) of <U1"),
    (np.full((500, 6), np.nan), "3000 action values are not finite"),
])
def test_a_table_that_does_not_fit_is_refused_in_one_line(tmp_path, content, message):
    np.save(tmp_path / "q.npy", content)
    with pytest.raises(AgentError) as caught:
        load(f"qtable:{tmp_path / 'q.npy'}")
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_a_pickle_or_an_archive_is_refused_without_running_it(tmp_path):
    class Boom:
        def __reduce__(self):
            return (exec, ("raise SystemExit('ran')",))

    np.save(tmp_path / "objects.npy", np.array([Boom()], dtype=object), allow_pickle=True)
    with pytest.raises(AgentError, match="not a NumPy .npy array"):
        load(f"qtable:{tmp_path / 'objects.npy'}")
    (tmp_path / "pickle.npy").write_bytes(pickle.dumps(np.zeros((500, 6))))
    with pytest.raises(AgentError, match="not a NumPy .npy array"):
        load(f"qtable:{tmp_path / 'pickle.npy'}")
    np.savez(tmp_path / "two.npz", a=np.zeros((500, 6)), b=np.zeros(3))
    with pytest.raises(AgentError, match=r"an .npz archive \(a, b\)"):
        load(f"qtable:{tmp_path / 'two.npz'}")
    with pytest.raises(AgentError, match="no such Q-table file|Q-table file"):
        load(f"qtable:{tmp_path / 'missing.npy'}")


def test_an_environment_that_is_not_tabular_is_refused(tmp_path):
    np.save(tmp_path / "q.npy", np.zeros((4, 2)))
    with pytest.raises(AgentError, match="acts on Discrete observations and actions; this environment has Box"):
        load(f"qtable:{tmp_path / 'q.npy'}", gym.make("CartPole-v1"))
