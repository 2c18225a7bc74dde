"""Parameter-free features of a grid level, read from its one-hot cells: shortest-path distances, a random
walker's visits and whole-level connectivity scalars (none in the paper).

Any grid domain whose one-hot channels mark the free cells, the start and the goal can use them; the Maze does.
They are inputs to a surrogate network (:class:`~dsage_ray.surrogate.models.WithInputFields`, or the
``statistics`` of :class:`~dsage_ray.surrogate.models.TwoStageModel`), judged by
``benchmarks/bench_surrogate_ceiling.py``, and a prior of a measure (:mod:`dsage_ray.domains.maze.prior`). No run
uses them unless a caller builds them in.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F


class Distances(NamedTuple):
    """BFS distances on a batch of ``n`` grid levels (:meth:`DistanceFields.distances`).

    Attributes:
        free: Bool ``(n, S, S)``, the cells an agent can stand on.
        from_start: ``(n, S, S)`` float steps from the start cell, -1 where not reached.
        to_goal: ``(n, S, S)`` float steps to the goal cell, -1 where not reached.
        length: ``(n,)`` the shortest start-goal distance (0 when the goal is not reached).
        start: Bool ``(n, S, S)``, the start cell.
        goal: Bool ``(n, S, S)``, the goal cell.
    """

    free: torch.Tensor
    from_start: torch.Tensor
    to_goal: torch.Tensor
    length: torch.Tensor
    start: torch.Tensor
    goal: torch.Tensor


class _GridChannels(nn.Module):
    """Parameter-free fields of a grid level, read from its one-hot channels (free cells, start, goal)."""

    def __init__(self, *, free_channels: tuple[int, ...], start_channel: int, goal_channel: int,
                 norm: float) -> None:
        super().__init__()
        self.free_channels = tuple(free_channels)
        self.start_channel = start_channel
        self.goal_channel = goal_channel
        self.norm = float(norm)


class DistanceFields(_GridChannels):
    """Parameter-free input channels: shortest-path distances on the level's grid, computed from its one-hot cells.

    Not in the paper, and not used by any run unless a caller wraps a model with it (off by default;
    ``benchmarks/bench_surrogate_ceiling.py`` judges it). For each level it runs a 4-neighbour BFS
    from the start cell and from the goal cell over the free cells, then appends three channels, each
    divided by ``norm`` and 0 where a cell is not reachable: the distance from the start, the distance
    to the goal, and the detour of a path through the cell, ``d_start + d_goal - d_start(goal)`` (0 on
    every shortest start-goal path). A 3×3 convolution stack sees 11×11 cells; these fields carry the
    whole maze's connectivity to every cell in one input.

    Args:
        free_channels: One-hot channels of the cells an agent can stand on (floor, start, goal).
        start_channel: The channel marking the start cell.
        goal_channel: The channel marking the goal cell.
        norm: Divisor of the distances (e.g. ``H·W / 2``, so most values lie in [0, 1]).
    """

    fields = 3

    @staticmethod
    def bfs(free: torch.Tensor, source: torch.Tensor) -> torch.Tensor:
        """Distances ``(n, S, S)`` from the ``source`` cells over ``free`` (both bool ``(n, S, S)``); -1 unreached."""
        distance = torch.full(free.shape, -1.0, device=free.device)
        reached = source & free
        distance[reached] = 0.0
        frontier = reached
        step = 0
        while True:
            step += 1
            grown = frontier.clone()
            grown[:, 1:] |= frontier[:, :-1]
            grown[:, :-1] |= frontier[:, 1:]
            grown[:, :, 1:] |= frontier[:, :, :-1]
            grown[:, :, :-1] |= frontier[:, :, 1:]
            frontier = grown & free & ~reached
            if not bool(frontier.any()):
                return distance
            distance[frontier] = float(step)
            reached = reached | frontier

    def distances(self, levels: torch.Tensor) -> "Distances":
        """The free cells and the BFS distances of ``(n, C, S, S)`` one-hot levels (:class:`Distances`)."""
        with torch.no_grad():
            cells = levels > 0.5
            free = cells[:, list(self.free_channels)].any(dim=1)
            # Both searches in one batch: half the steps of the loop.
            from_start, to_goal = self.bfs(torch.cat([free, free]),
                                           torch.cat([cells[:, self.start_channel], cells[:, self.goal_channel]])
                                           ).chunk(2)
            length = (from_start * cells[:, self.goal_channel]).sum(dim=(1, 2))
        return Distances(free=free, from_start=from_start, to_goal=to_goal, length=length,
                         start=cells[:, self.start_channel], goal=cells[:, self.goal_channel])

    def forward(self, levels: torch.Tensor) -> torch.Tensor:
        """``(n, C, S, S)`` one-hot levels → ``(n, C + 3, S, S)``: the levels, then the three fields."""
        d = self.distances(levels)
        reachable = (d.from_start >= 0) & (d.to_goal >= 0)
        detour = d.from_start + d.to_goal - d.length[:, None, None]
        stacked = torch.stack([d.from_start, d.to_goal, detour], dim=1) * reachable[:, None] / self.norm
        return torch.cat([levels, stacked.to(levels.dtype)], dim=1)


def _count(mask: torch.Tensor) -> torch.Tensor:
    """``(n, S, S)`` bool → ``(n,)`` float: the true cells of each level."""
    return mask.sum(dim=(1, 2)).float()


class LevelStatistics(nn.Module):
    """Parameter-free per-level scalars of a grid level's connectivity, for the measure heads (not in the paper).

    A convolutional network reads local patterns; these are the whole-maze facts a gradient-boosted model
    on hand-made BFS features ranks ACCEL's path lengths with (``benchmarks/bench_surrogate_ceiling.py``):
    the shortest start-goal distance, the reachable area and the cells on a shortest path, dead ends and
    junctions (all, and on a shortest path), the distances from the start and the detours through cells
    (mean and max), the cells within 2, 6 and 12 steps of a shortest path, the walls, the start-goal
    Manhattan distance and the path's ratio to it. Distances are divided by ``norm``, counts by the area.

    Args:
        fields: The BFS on the level's one-hot cells (its ``free_channels``, start and goal).
        norm: Divisor of distances (e.g. ``H·W / 2``).
    """

    names = ("optimal_path", "reachable", "on_shortest_paths", "dead_ends", "junctions", "shortest_path_junctions",
             "mean_from_start", "max_from_start", "mean_detour", "max_detour", "detour<=2", "detour<=6",
             "detour<=12", "walls", "manhattan", "path/manhattan")
    size = len(names)

    def __init__(self, *, fields: DistanceFields, norm: float) -> None:
        super().__init__()
        self.fields = fields
        self.norm = float(norm)

    def forward(self, levels: torch.Tensor) -> torch.Tensor:
        """``(n, C, S, S)`` one-hot levels → ``(n, size)`` float32 scalars."""
        with torch.no_grad():
            d = self.fields.distances(levels)
            size = levels.shape[-1]
            area = float(size * size)
            reach = d.from_start >= 0
            both = reach & (d.to_goal >= 0)
            detour = torch.where(both, d.from_start + d.to_goal - d.length[:, None, None], torch.zeros_like(d.to_goal))
            on_path = both & (detour == 0)
            free = d.free.float()
            neighbours = torch.tensor([[[[0.0, 1, 0], [1, 0, 1], [0, 1, 0]]]], device=levels.device)
            degree = F.conv2d(free[:, None], neighbours, padding=1)[:, 0]  # free 4-neighbours of each cell
            reach_count = _count(reach).clamp(min=1)
            both_count = _count(both).clamp(min=1)
            coords = torch.arange(size, device=levels.device, dtype=torch.float32)

            def position(mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
                mask = mask.float()
                return (mask.sum(dim=2) * coords).sum(dim=1), (mask.sum(dim=1) * coords).sum(dim=1)

            (start_row, start_col), (goal_row, goal_col) = position(d.start), position(d.goal)
            manhattan = (start_row - goal_row).abs() + (start_col - goal_col).abs()
            scalars = torch.stack([
                d.length / self.norm,
                _count(reach) / area,
                _count(on_path) / area,
                _count(reach & (degree == 1)) / area,
                _count(reach & (degree >= 3)) / area,
                _count(on_path & (degree >= 3)) / area,
                (d.from_start * reach).sum(dim=(1, 2)) / reach_count / self.norm,
                d.from_start.amax(dim=(1, 2)).clamp(min=0) / self.norm,
                (detour * both).sum(dim=(1, 2)) / both_count / self.norm,
                detour.amax(dim=(1, 2)) / self.norm,
                _count(both & (detour <= 2)) / area,
                _count(both & (detour <= 6)) / area,
                _count(both & (detour <= 12)) / area,
                1.0 - free.sum(dim=(1, 2)) / area,
                manhattan / (2 * size),
                d.length / manhattan.clamp(min=1) / 4,
            ], dim=1)
        return scalars.to(levels.dtype)


class RandomWalkFields(_GridChannels):
    """Parameter-free input channel: where a uniform random walker goes on the level before it finds the goal.

    Not in the paper. A walker starts on the start cell and moves to one of its free 4-neighbours uniformly
    each step until it enters the goal. Its expected number of visits to each cell is the Green's function of
    the grid's random walk with the goal absorbing: ``v_j = deg_j · x_j`` with ``L x = e_start``, ``L`` the
    graph Laplacian of the cells reachable from the start, less the goal (symmetric, so one banded Cholesky
    solve per level, on the CPU). The visits sum to the walker's expected steps to the goal, its hitting time,
    which ranks ACCEL's mean path length better than the shortest path does: the Maze's
    ``surrogate.prior_measure`` (:mod:`dsage_ray.domains.maze.prior`) blends it into the surrogate's path
    length. As an input channel, ``log1p(visits) / norm``, it is a benchmark setting only
    (``benchmarks/bench_surrogate_ceiling.py``); :meth:`visits` gives the raw field.

    Args:
        free_channels: One-hot channels of the cells an agent can stand on (floor, start, goal).
        start_channel: The channel marking the start cell.
        goal_channel: The channel marking the goal cell.
        norm: Divisor of the log visits (e.g. ``log1p(H·W)``, so most values lie in [0, 1]).
    """

    fields = 1

    def visits(self, levels: torch.Tensor) -> torch.Tensor:
        """``(n, C, S, S)`` one-hot levels → ``(n, S, S)`` float64 expected visits (0 off the walker's cells)."""
        from scipy import ndimage
        from scipy.linalg.lapack import dpbsv

        cells = (levels.detach() > 0.5).cpu().numpy()
        free_cells = cells[:, list(self.free_channels)].any(axis=1)
        start, goal = cells[:, self.start_channel] & free_cells, cells[:, self.goal_channel]
        # The walker's cells: the start's 4-connected component (one labelling for the whole batch; the
        # structure links no two levels), less the goal.
        cross = np.zeros((3, 3, 3), dtype=bool)
        cross[1] = ndimage.generate_binary_structure(2, 1)
        labels, _ = ndimage.label(free_cells, structure=cross)
        start_label = (labels * start).reshape(len(labels), -1).max(axis=1)
        active = (labels == start_label[:, None, None]) & (start_label[:, None, None] > 0) & ~goal
        start = start & active
        n, size, _ = active.shape
        area = size * size
        # Row-major cells make the Laplacian a band matrix of half-width ``size`` (a neighbour is at most a row
        # away), so LAPACK's banded Cholesky solves it in O(area · size²) instead of O(area³).
        padded = np.pad(active, ((0, 0), (1, 1), (1, 1)))
        free = np.pad(free_cells, ((0, 0), (1, 1), (1, 1)))
        degree = (free[:, :-2, 1:-1].astype(np.float64) + free[:, 2:, 1:-1] + free[:, 1:-1, :-2]
                  + free[:, 1:-1, 2:]).reshape(n, area)
        flat = active.reshape(n, area)
        left_link = (padded[:, 1:-1, 1:-1] & padded[:, 1:-1, :-2]).reshape(n, area)
        up_link = (padded[:, 1:-1, 1:-1] & padded[:, :-2, 1:-1]).reshape(n, area)
        band = np.zeros((n, size + 1, area))  # LAPACK's upper band storage: band[size + i - j, j] = L[i, j]
        band[:, size] = np.where(flat, degree, 1.0)
        band[:, size - 1, 1:] = -left_link[:, 1:].astype(np.float64)
        band[:, 0, size:] = -up_link[:, size:].astype(np.float64)
        rhs = start.reshape(n, area).astype(np.float64)
        visits = np.zeros((n, area))
        for m in np.flatnonzero(rhs.any(axis=1)):
            _, solved, info = dpbsv(band[m], rhs[m])
            if info != 0:
                raise RuntimeError(f"random-walk Laplacian of level {m} is not positive definite (LAPACK {info})")
            visits[m] = np.where(flat[m], degree[m] * solved, 0.0)
        return torch.from_numpy(visits.reshape(n, size, size)).to(levels.device)

    def forward(self, levels: torch.Tensor) -> torch.Tensor:
        """``(n, C, S, S)`` one-hot levels → ``(n, C + 1, S, S)``: the levels, then the log visits."""
        field = torch.log1p(self.visits(levels)) / self.norm
        return torch.cat([levels, field.unsqueeze(1).to(levels.dtype)], dim=1)
