"""The DCD agent's precomputed inference step against the plain module-by-module computation it replaced.

The fast step (dense conv matrix, heading/bias table, two ``addmm`` into the LSTM gates) sums float32 terms in a
different order, so logits may differ in the last bits; these tests bound the difference and check that the real
ACCEL checkpoint still takes exactly the same actions, i.e. evaluations give the same results.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.dcd import DCDAgent
from dsage_ray.domains.maze import MazeLevel, evaluate
from tests.domains.maze.agents.conftest import ACCEL_SPEC
from tests.domains.maze.agents.mazes import labyrinth13, open_maze, perfect_maze
from tests.domains.maze.agents.test_dcd import random_obs


class ModuleDCDAgent(DCDAgent):
    """The agent as first written: the checkpoint's modules called one by one, the LSTM through an LSTMCell."""

    def __init__(self, agent: DCDAgent) -> None:
        super().__init__(network=agent.network, heading_quirk=agent.heading_quirk, quirk_group=agent.quirk_group)
        lstm = self.network.rnn.rnn
        self._cell = torch.nn.LSTMCell(lstm.input_size, lstm.hidden_size)
        self._cell.load_state_dict({k.removesuffix("_l0"): v for k, v in lstm.state_dict().items()})

    def logits(self, obs, state):
        net = self.network
        with torch.inference_mode():
            image = torch.from_numpy(np.ascontiguousarray(obs["image"])).permute(0, 3, 1, 2).float() / 10.0
            in_image = net.image_conv(image)
            in_scalar = net.scalar_embed(torch.from_numpy(self.heading_onehot(np.asarray(obs["direction"]))))
            h, c = self._cell(torch.cat((in_image, in_scalar), dim=1), state)
            return net.actor(h), (h, c)


@pytest.mark.parametrize("options", ["", "?heading_quirk=1", "?heading_quirk=1&quirk_group=3"])
def test_step_matches_the_module_computation(random_dcd_checkpoint, options):
    fast = load_maze_agent(f"dcd:{random_dcd_checkpoint}{options}")
    slow = ModuleDCDAgent(fast)
    obs_rng = np.random.default_rng(0)
    for n in (1, 7, 50):
        fast_state, slow_state = fast.initial_state(n), slow.initial_state(n)
        for _ in range(15):
            obs = random_obs(obs_rng, n)
            fast_logits, fast_state = fast.logits(obs, fast_state)
            slow_logits, slow_state = slow.logits(obs, slow_state)
            torch.testing.assert_close(fast_logits, slow_logits, rtol=1e-5, atol=1e-5)
            for a, b in zip(fast_state, slow_state):
                torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)


def _random_16x16(seed: int) -> MazeLevel:
    rng = np.random.default_rng(seed)
    while not (level := MazeLevel.from_bitmap(rng.random((16, 16)) < 0.3)).valid:
        pass
    return level


@pytest.mark.parametrize(
    "make",
    [labyrinth13, lambda: open_maze(13, 0.1, 0), lambda: perfect_maze(15, 0), lambda: _random_16x16(0),
     lambda: _random_16x16(1)],
    ids=["labyrinth13", "open13", "perfect15", "random16-0", "random16-1"],
)
def test_accel_evaluations_are_unchanged(make):
    """Same seed, same level: the fast step and the module computation take identical actions in every episode."""
    fast = load_maze_agent(ACCEL_SPEC)
    slow = ModuleDCDAgent(fast)
    level = make()
    a, b = evaluate(level, fast, episodes=50, seed=3), evaluate(level, slow, episodes=50, seed=3)
    np.testing.assert_array_equal(a.episode_lengths, b.episode_lengths)
    np.testing.assert_array_equal(a.successes, b.successes)
    np.testing.assert_array_equal(a.occupancy, b.occupancy)


def test_reduced_precision_is_close_to_the_agent_and_leaves_it_as_it_was():
    """The bf16 copy (the screen's) rounds the matrix products, so its logits are near, not equal to, the agent's;
    on a real level it plays about as the agent does; the agent itself keeps float32."""
    agent = load_maze_agent(ACCEL_SPEC)
    reduced = agent.reduced_precision()
    assert reduced is not agent and reduced._step.w_hidden.dtype == torch.bfloat16
    assert agent._step.w_hidden.dtype == torch.float32
    obs_rng = np.random.default_rng(1)
    state, reduced_state = agent.initial_state(20), reduced.initial_state(20)
    for _ in range(10):
        obs = random_obs(obs_rng, 20)
        logits, state = agent.logits(obs, state)
        reduced_logits, reduced_state = reduced.logits(obs, reduced_state)
        assert reduced_logits.dtype == torch.float32 and reduced_state[1].dtype == torch.float32
        torch.testing.assert_close(reduced_logits, logits, rtol=0.1, atol=0.1)
    level = _random_16x16(2)
    full, screened = evaluate(level, agent, episodes=50, seed=5), evaluate(level, reduced, episodes=50, seed=5)
    assert abs(full.mean_path_length - screened.mean_path_length) < 0.25 * full.mean_path_length + 10
    # The float32 agent is untouched: the same evaluation again, bit for bit.
    again = evaluate(level, agent, episodes=50, seed=5)
    np.testing.assert_array_equal(again.episode_lengths, full.episode_lengths)


def test_only_agents_with_a_reduced_copy_offer_one():
    assert load_maze_agent("builtin:wall_follower").reduced_precision() is None
