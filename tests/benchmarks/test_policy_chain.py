"""The policy chain's propagation must be MiniGrid's dynamics, exactly, for any controller."""

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from dsage_ray.domains.maze.level import MazeLevel  # noqa: E402
from dsage_ray.domains.maze.simulator import (FORWARD, LEFT, RIGHT, BatchedMazeSimulator, cell_kinds,  # noqa: E402
                                              view_tables)
from policy_chain import (  # noqa: E402
    ACTIONS, PolicyChain, chain_inputs, chain_loss, flops_per_level, predict_path_length, train_chain,
)

WALLS = np.array([
    [0, 0, 0, 1, 0],
    [0, 1, 0, 1, 0],
    [0, 1, 0, 0, 0],
    [0, 0, 0, 1, 1],
], dtype=bool)


def _fixed_policy(chain: PolicyChain, action_probabilities, mode_probabilities=None) -> PolicyChain:
    """Makes ``chain`` draw actions (and next modes) with fixed probabilities, whatever it sees."""
    modes = mode_probabilities if mode_probabilities is not None else np.ones(chain.modes) / chain.modes
    last = chain.policy[-1]
    with torch.no_grad():
        last.weight.zero_()
        joint = np.log(np.outer(action_probabilities, modes)).ravel()
        last.bias.copy_(torch.tensor(joint, dtype=torch.float32))
    return chain


def _monte_carlo(level: MazeLevel, action_probabilities, *, episodes: int, max_steps: int, seed: int):
    """Mean occupancy and path length of a memoryless agent drawing MiniGrid actions with fixed probabilities."""
    rng = np.random.default_rng(seed)
    sim = BatchedMazeSimulator(level, max_steps=max_steps)
    sim.reset(rng.integers(0, 4, size=episodes))
    # "stay" is spread over MiniGrid's four actions that do nothing in a maze.
    probabilities = np.array([*action_probabilities[:3], *[action_probabilities[3] / 4] * 4])
    assert (LEFT, RIGHT, FORWARD) == (0, 1, 2)
    occupancy = np.zeros(level.walls.shape)
    lengths = np.zeros(episodes)
    running = np.arange(episodes)
    while len(running):
        np.add.at(occupancy, (sim.positions[:, 1] - 1, sim.positions[:, 0] - 1), 1.0)
        _, _, terminated, truncated = sim.step(rng.choice(len(probabilities), size=len(running), p=probabilities))
        lengths[running] = sim.step_counts
        keep = ~(terminated | truncated)
        running = running[keep]
        sim.keep(np.flatnonzero(keep))
    return occupancy / episodes, lengths


@pytest.mark.parametrize("probabilities", [(0.2, 0.2, 0.5, 0.1), (0.05, 0.35, 0.3, 0.3)])
def test_expected_occupancy_matches_simulated_agents(probabilities):
    level = MazeLevel.from_bitmap(WALLS)
    max_steps = 40  # short, so that some episodes are cut off and truncation is exercised
    chain = _fixed_policy(PolicyChain(max_steps=max_steps, modes=1), probabilities)
    occupancy = chain(chain_inputs(WALLS[None]))[0].detach().numpy()
    simulated, lengths = _monte_carlo(level, probabilities, episodes=20000, max_steps=max_steps, seed=0)
    assert (lengths == max_steps).any() and (lengths < max_steps).any()
    standard_error = lengths.std() / np.sqrt(len(lengths))
    assert abs(occupancy.sum() - lengths.mean()) < 4 * standard_error
    assert np.abs(occupancy - simulated).max() < 0.25
    assert occupancy[level.goal] == 0 and (occupancy[WALLS] == 0).all()
    assert occupancy[level.start] >= 1.0  # every episode begins its first step there


def test_a_mode_the_policy_ignores_changes_nothing():
    probabilities = (0.25, 0.15, 0.45, 0.15)
    one = _fixed_policy(PolicyChain(max_steps=60, modes=1), probabilities)
    three = _fixed_policy(PolicyChain(max_steps=60, modes=3), probabilities, mode_probabilities=(0.5, 0.3, 0.2))
    inputs = chain_inputs(WALLS[None])
    torch.testing.assert_close(three(inputs), one(inputs))


def test_views_are_the_agents_views():
    level = MazeLevel.from_bitmap(WALLS)
    inputs = chain_inputs(WALLS[None])
    tables = view_tables(cell_kinds(level)[None])[0]  # (W+2, H+2, 4, 5, 5, 3) MiniGrid images
    kinds = {(1, 0): 0, (2, 5): 1, (8, 1): 2}  # MiniGrid (object, colour) -> the chain's one-hot index
    for y in range(WALLS.shape[0]):
        for x in range(WALLS.shape[1]):
            for heading in range(4):
                image = tables[x + 1, y + 1, heading]
                expected = np.array([[kinds[(int(c[0]), int(c[1]))] for c in row] for row in image])
                onehot = inputs.views[0, heading, y, x].view(-1, 3).numpy()
                assert (onehot.argmax(axis=1).reshape(5, 5) == expected).all(), (y, x, heading)


def test_a_level_without_a_pair_predicts_zero():
    walls = np.ones((2, 4, 5), dtype=bool)
    walls[1] = WALLS[:, :]
    chain = PolicyChain(max_steps=30)
    lengths = predict_path_length(chain, walls)
    assert lengths[0] == 0 and 0 < lengths[1] <= 30


def test_training_lowers_the_loss_and_gradients_are_finite():
    rng = np.random.default_rng(0)
    walls = np.stack([WALLS, WALLS[::-1], WALLS[:, ::-1]])
    truth = _fixed_policy(PolicyChain(max_steps=30, modes=1), (0.1, 0.1, 0.7, 0.1))
    with torch.no_grad():
        occupancy = truth(chain_inputs(walls)).numpy()
    chain = PolicyChain(max_steps=30, modes=2, hidden=16)
    torch.manual_seed(int(rng.integers(1000)))
    losses = train_chain(chain, walls, occupancy, occupancy.sum(axis=(1, 2)), epochs=15, batch_size=3, lr=1e-2)
    assert losses[-1] < 0.5 * losses[0]
    loss = chain_loss(chain(chain_inputs(walls)), torch.from_numpy(occupancy),
                      torch.from_numpy(occupancy.sum(axis=(1, 2))))
    loss.backward()
    assert all(torch.isfinite(p.grad).all() for p in chain.parameters())


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="max_steps, modes and hidden"):
        PolicyChain(max_steps=0)
    with pytest.raises(ValueError, match=r"\(n, H, W\)"):
        chain_inputs(WALLS)
    with pytest.raises(ValueError, match="same levels"):
        train_chain(PolicyChain(max_steps=5), WALLS[None], np.zeros((2, 4, 5)), np.zeros(1), epochs=1)
    with pytest.raises(ValueError, match="same view_size"):
        PolicyChain(max_steps=5, view_size=3)(chain_inputs(WALLS[None], view_size=5))
    assert len(ACTIONS) == 4 and flops_per_level(PolicyChain(max_steps=10), 4, 5) > 0
