"""A learned policy, propagated exactly: a surrogate family that models how the agent moves (not in the paper).

The convolutional surrogate maps a maze to its measures. A :class:`PolicyChain` instead learns a stochastic
finite-state controller that stands in for the agent: in the state (cell, heading, mode) it draws an action
(turn left, turn right, forward, or one of MiniGrid's actions that do nothing in a maze) and its next mode, from
the egocentric view the agent would see there, its heading and its mode. The modes are a small memory, the
part of an LSTM agent's state that a memoryless walker lacks. The expected occupancy of that controller over
the episode's step limit is computed exactly, by moving the distribution over states forward one step at a time
with MiniGrid's dynamics: a step into a wall stays, a step onto the goal ends the episode. So the path length
(the occupancy's sum) is differentiable in the controller, which is trained on the agent's measured occupancy
and mean path length.

With 4 modes it ranks ACCEL's path length on a search's own levels as well as the network or better, with a
lower error; without memory it is the worst model measured (``docs/results/surrogate_accuracy``, "A learned
policy chain"). Per level it costs hundreds of times the network (the propagation is ``max_steps`` small steps
over ``modes² × 4 × H × W`` state pairs), so it is a benchmark model family
(``bench_surrogate_ceiling.py --setting NAME:bench.chain=MODES``), not a run's surrogate, and lives beside the
benchmarks rather than in the package.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch
from torch import nn

from dsage_ray.domains.maze.paths import furthest_pairs
from dsage_ray.domains.maze.simulator import DIR_TO_VEC, EMPTY, GOAL, WALL, view_kinds
#: The controller's actions: MiniGrid's left, right, forward, and the four that do nothing in a maze
#: (pickup, drop, toggle, done), as one.
ACTIONS = ("left", "right", "forward", "stay")


@dataclasses.dataclass(frozen=True)
class ChainInputs:
    """What the chain reads of a batch of ``n`` levels of one size ``H × W`` (interior coordinates).

    Attributes:
        views: ``(n, 4, H, W, 3·s·s)`` float32: per heading and cell, the one-hot (empty, wall, goal) of each
            cell of the ``s × s`` egocentric view (MiniGrid's, walls seen through; the agent's own cell empty).
        blocked: ``(n, 4, H, W)`` float32: 1 where forward from that cell and heading hits a wall or the border.
        moves: ``(n, 4, H, W)`` float32: 1 where forward enters an empty cell (not the goal).
        start: ``(n, H, W)`` float32: one-hot of the start; all zero for a level without a start-goal pair.
    """

    views: torch.Tensor
    blocked: torch.Tensor
    moves: torch.Tensor
    start: torch.Tensor


def chain_inputs(walls: np.ndarray, *, pairs: np.ndarray | None = None, view_size: int = 5) -> ChainInputs:
    """The chain's inputs for a batch of mazes.

    Args:
        walls: ``(n, H, W)`` bool interior wall bitmaps.
        pairs: ``(n, ≥2)`` flat (row-major) start and goal indices, -1 without a pair; default the domain's
            furthest connected pair (:func:`~dsage_ray.domains.maze.paths.furthest_pairs`).
        view_size: The agent's egocentric view side (odd).

    Returns:
        The :class:`ChainInputs`.
    """
    walls = np.asarray(walls, dtype=bool)
    if walls.ndim != 3:
        raise ValueError(f"expected (n, H, W) wall bitmaps, got shape {walls.shape}")
    n, height, width = walls.shape
    pairs = furthest_pairs(walls) if pairs is None else np.asarray(pairs, dtype=np.int64)
    has_pair = pairs[:, 0] >= 0
    rows = np.arange(n)[has_pair]
    goal_y, goal_x = np.divmod(pairs[has_pair, 1], width)
    start_y, start_x = np.divmod(pairs[has_pair, 0], width)
    kinds = np.full((n, height + 2, width + 2), WALL, dtype=np.int8)  # padded, [y, x]
    kinds[:, 1:-1, 1:-1] = np.where(walls, WALL, EMPTY)
    kinds[rows, goal_y + 1, goal_x + 1] = GOAL
    view = view_kinds(kinds.transpose(0, 2, 1), agent_view_size=view_size)  # the simulator's [x, y] cell_kinds
    view = view.reshape(n, width + 2, height + 2, 4, view_size * view_size)[:, 1:-1, 1:-1]
    view = view.transpose(0, 3, 2, 1, 4)  # (n, 4, H, W, s·s)
    onehot = np.eye(3, dtype=np.float32)[view].reshape(n, 4, height, width, 3 * view_size * view_size)
    ahead = np.stack([kinds[:, 1 + dy:height + 1 + dy, 1 + dx:width + 1 + dx] for dx, dy in DIR_TO_VEC], axis=1)
    start = np.zeros((n, height, width), dtype=np.float32)
    start[rows, start_y, start_x] = 1.0
    return ChainInputs(views=torch.from_numpy(onehot), blocked=torch.from_numpy((ahead == WALL).astype(np.float32)),
                       moves=torch.from_numpy((ahead == EMPTY).astype(np.float32)), start=torch.from_numpy(start))


class PolicyChain(nn.Module):
    """A stochastic finite-state controller over MiniGrid's maze dynamics, with its exact expected occupancy.

    Args:
        max_steps: The episode step limit (the Maze's ``2·(H+2)·(W+2)``).
        modes: Memory modes (1: a memoryless policy).
        hidden: Units of each of the policy's two hidden layers.
        view_size: The egocentric view side the policy reads (the agent's).

    The episode starts in mode 0 at the start cell, its heading uniform (MiniGrid draws it at random).
    """

    def __init__(self, *, max_steps: int, modes: int = 2, hidden: int = 64, view_size: int = 5) -> None:
        super().__init__()
        if max_steps < 1 or modes < 1 or hidden < 1:
            raise ValueError(f"max_steps, modes and hidden must be >= 1, got {max_steps}, {modes}, {hidden}")
        self.max_steps = max_steps
        self.modes = modes
        self.view_features = 3 * view_size * view_size
        self.policy = nn.Sequential(
            nn.Linear(self.view_features + 4 + modes, hidden), nn.ReLU(),
            nn.Linear(hidden, hidden), nn.ReLU(),
            nn.Linear(hidden, len(ACTIONS) * modes),
        )

    def action_probabilities(self, inputs: ChainInputs) -> torch.Tensor:
        """``(n, modes, actions, next modes, 4, H, W)``: the controller's joint distribution per state."""
        n, _, height, width, features = inputs.views.shape
        if features != self.view_features:
            raise ValueError(f"the inputs' views hold {features} features per state, this chain reads "
                             f"{self.view_features}: build both with the same view_size")
        k = self.modes
        heading = torch.eye(4).view(1, 1, 4, 1, 1, 4).expand(n, k, 4, height, width, 4)
        mode = torch.eye(k).view(1, k, 1, 1, 1, k).expand(n, k, 4, height, width, k)
        views = inputs.views.unsqueeze(1).expand(n, k, 4, height, width, features)
        logits = self.policy(torch.cat([views, heading, mode], dim=-1))
        probabilities = torch.softmax(logits, dim=-1).view(n, k, 4, height, width, len(ACTIONS), k)
        return probabilities.permute(0, 1, 5, 6, 2, 3, 4)

    def forward(self, inputs: ChainInputs) -> torch.Tensor:
        """``(n, H, W)``: expected steps begun on each cell, as the Maze's occupancy counts them (the start
        counted, the goal never); its sum is the expected path length, a failed episode counting ``max_steps``."""
        n, _, height, width = inputs.blocked.shape
        k = self.modes
        probabilities = self.action_probabilities(inputs)
        left, right, forward, stay = probabilities.unbind(dim=2)  # each (n, k, k', 4, H, W)
        blocked = inputs.blocked.view(n, 1, 1, 4, height, width)
        stays = stay + forward * blocked
        moves = forward * inputs.moves.view(n, 1, 1, 4, height, width)  # a step onto the goal leaves the chain
        mass = torch.zeros(n, k, 4, height, width)
        mass[:, 0] = inputs.start.unsqueeze(1) / 4.0
        occupancy = torch.zeros(n, height, width)
        for _ in range(self.max_steps):
            occupancy = occupancy + mass.sum(dim=(1, 2))
            here = mass.unsqueeze(2)  # (n, k, 1, 4, H, W), summed over the current mode below
            turned_left = (here * left).sum(dim=1)
            turned_right = (here * right).sum(dim=1)
            moved = (here * moves).sum(dim=1)
            mass = ((here * stays).sum(dim=1) + torch.roll(turned_left, -1, dims=2) + torch.roll(turned_right, 1, dims=2)
                    + torch.stack([torch.roll(moved[:, :, d], shifts=(int(dy), int(dx)), dims=(2, 3))
                                   for d, (dx, dy) in enumerate(DIR_TO_VEC)], dim=2))
        return occupancy


def chain_loss(occupancy: torch.Tensor, target_occupancy: torch.Tensor, path_length: torch.Tensor, *,
               occupancy_weight: float = 0.1) -> torch.Tensor:
    """Squared error of ``log(1 + path length)`` plus ``occupancy_weight`` × the per-cell occupancy's squared error.

    The log keeps short paths from drowning in failures (648 steps); the occupancy tells the controller where
    the agent spends its steps, not only how many."""
    predicted = occupancy.sum(dim=(1, 2))
    return (((torch.log1p(predicted) - torch.log1p(path_length)) ** 2).mean()
            + occupancy_weight * ((occupancy - target_occupancy) ** 2).mean())


def train_chain(chain: PolicyChain, walls: np.ndarray, occupancy: np.ndarray, path_length: np.ndarray, *,
                epochs: int, batch_size: int = 16, lr: float = 3e-3, seed: int = 0,
                occupancy_weight: float = 0.1) -> list[float]:
    """Trains ``chain`` with Adam on levels and what the agent did on them; returns each epoch's mean loss.

    Args:
        chain: The controller (trained in place).
        walls: ``(n, H, W)`` bool wall bitmaps.
        occupancy: ``(n, H, W)`` the agent's measured occupancy (mean steps begun per cell).
        path_length: ``(n,)`` the agent's mean path length.
        epochs: Passes over the levels.
        batch_size: Levels per step.
        lr: Adam's learning rate.
        seed: The minibatch order's seed (the weights were drawn when ``chain`` was built).
        occupancy_weight: :func:`chain_loss`'s weight.
    """
    walls = np.asarray(walls, dtype=bool)
    occupancy = torch.as_tensor(np.asarray(occupancy, dtype=np.float32))
    path_length = torch.as_tensor(np.asarray(path_length, dtype=np.float32))
    if not (len(walls) == len(occupancy) == len(path_length)) or occupancy.shape[1:] != walls.shape[1:]:
        raise ValueError(f"walls {walls.shape}, occupancy {tuple(occupancy.shape)} and path_length "
                         f"{tuple(path_length.shape)} must describe the same levels")
    optimizer = torch.optim.Adam(chain.parameters(), lr=lr)
    rng = np.random.default_rng(seed)
    losses = []
    chain.train()
    for _ in range(epochs):
        order = rng.permutation(len(walls))
        total = 0.0
        for first in range(0, len(order), batch_size):
            rows = order[first:first + batch_size]
            loss = chain_loss(chain(chain_inputs(walls[rows])), occupancy[rows], path_length[rows],
                              occupancy_weight=occupancy_weight)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * len(rows)
        losses.append(total / max(len(order), 1))
    return losses


def predict_path_length(chain: PolicyChain, walls: np.ndarray, *, batch_size: int = 100) -> np.ndarray:
    """``(n,)`` float64: the chain's expected path length per level (0 without a start-goal pair)."""
    walls = np.asarray(walls, dtype=bool)
    chain.eval()
    out = np.zeros(len(walls))
    with torch.no_grad():
        for first in range(0, len(walls), batch_size):
            out[first:first + batch_size] = chain(chain_inputs(walls[first:first + batch_size])).sum(dim=(1, 2)).numpy()
    return out


def flops_per_level(chain: PolicyChain, height: int, width: int) -> float:
    """Floating-point operations of one level's prediction (multiply and add counted apart): the policy over
    every state, then ``max_steps`` propagation steps of about 16 operations per state and next mode."""
    states = chain.modes * 4 * height * width
    layers = [layer for layer in chain.policy if isinstance(layer, nn.Linear)]
    policy = sum(2 * layer.in_features * layer.out_features for layer in layers) * states
    return float(policy + chain.max_steps * 16 * states * chain.modes)
