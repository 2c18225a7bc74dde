"""A batched numpy re-implementation of :class:`~dsage_ray.domains.maze.env.MazeEnv`.

In a Maze the only thing that moves is the agent, so the egocentric observation is a function of
``(x, y, direction)`` alone. With many episodes per level the simulator renders it once for every such state
(a lookup table of ``(H+2)·(W+2)·4`` views per level); with a few (:data:`TABLE_EPISODES`), each step gathers
the views from the levels' cells instead. A step is a handful of fancy-index operations over the batch, whose
episodes may play different levels of one size.
Dynamics, rewards, termination, truncation and observations are bit-identical to MiniGrid 3.2 for
either ``see_through_walls`` setting (tested step by step in ``tests/domains/maze``).
"""

from __future__ import annotations

import functools
from typing import Sequence

import numpy as np

from dsage_ray.domains.maze.agents import constants as minigrid
from dsage_ray.domains.maze.agents.constants import FORWARD, LEFT, NUM_ACTIONS, RIGHT
from dsage_ray.domains.maze.level import MazeLevel

# Cell kinds in the padded grid; MiniGrid's (object, colour, state) encoding of each, as MiniGrid's
# Grid.encode writes them for an empty cell, a Wall() and a Goal().
EMPTY, WALL, GOAL = 0, 1, 2
_ENCODING = np.array([
    [minigrid.OBJECT_TO_IDX["empty"], 0, 0],
    [minigrid.OBJECT_TO_IDX["wall"], minigrid.COLOR_TO_IDX["grey"], 0],
    [minigrid.OBJECT_TO_IDX["goal"], minigrid.COLOR_TO_IDX["green"], 0],
], dtype=np.uint8)
#: MiniGrid's DIR_TO_VEC as (dx, dy): right, down, left, up.
DIR_TO_VEC = np.array(minigrid.DIR_TO_VEC, dtype=np.int64)


def cell_kinds(level: MazeLevel) -> np.ndarray:
    """``(W+2, H+2)`` cell kinds indexed ``[x, y]`` like MiniGrid: border and walls WALL, the goal GOAL."""
    kinds = np.full((level.width + 2, level.height + 2), WALL, dtype=np.int8)
    kinds[1:-1, 1:-1] = np.where(level.walls.T, WALL, EMPTY)
    if level.goal is not None:
        kinds[level.goal[1] + 1, level.goal[0] + 1] = GOAL
    return kinds


def _visibility(opaque: np.ndarray) -> np.ndarray:
    """MiniGrid's ``Grid.process_vis`` for a batch of views.

    Args:
        opaque: ``(n, s, s)`` bool indexed ``[view, i, j]`` (i across, j away from the agent's row);
            True where the cell blocks sight (a wall).

    Returns:
        ``(n, s, s)`` bool visibility mask, same indexing.
    """
    n, size, _ = opaque.shape
    mask = np.zeros_like(opaque)
    mask[:, size // 2, size - 1] = True
    # The same sweep as MiniGrid, one view-cell at a time but vectorised over all views; the
    # order matters (a cell marked visible earlier in a row spreads visibility further).
    for j in reversed(range(size)):
        for i in range(size - 1):
            spread = mask[:, i, j] & ~opaque[:, i, j]
            mask[:, i + 1, j] |= spread
            if j > 0:
                mask[:, i + 1, j - 1] |= spread
                mask[:, i, j - 1] |= spread
        for i in reversed(range(1, size)):
            spread = mask[:, i, j] & ~opaque[:, i, j]
            mask[:, i - 1, j] |= spread
            if j > 0:
                mask[:, i - 1, j - 1] |= spread
                mask[:, i, j - 1] |= spread
    return mask


@functools.lru_cache(maxsize=16)
def _view_cells(width: int, height: int, size: int) -> np.ndarray:
    """Where every view cell of every agent state looks, for a padded grid of ``width × height`` cells.

    The views depend on the level only through its cell kinds, so this index is computed once per grid size.

    Returns:
        ``(width·height·4, size, size)`` int64 flat ``[x, y]`` index into the padded grid's kinds, or
        ``width·height`` (one past the grid: read as a wall) where the view leaves the grid.
    """
    x, y, d = np.meshgrid(np.arange(width), np.arange(height), np.arange(4), indexing="ij")
    x, y, d = (a.reshape(-1, 1, 1) for a in (x, y, d))
    i = np.arange(size).reshape(1, size, 1)
    j = np.arange(size).reshape(1, 1, size)
    dx, dy = DIR_TO_VEC[d, 0], DIR_TO_VEC[d, 1]
    rx, ry = -dy, dx  # MiniGrid's right_vec
    ahead, across = size - 1 - j, i - size // 2
    wx = x + ahead * dx + across * rx
    wy = y + ahead * dy + across * ry
    inside = (wx >= 0) & (wx < width) & (wy >= 0) & (wy < height)
    cells = np.where(inside, wx * height + wy, width * height)
    cells.setflags(write=False)
    return cells


def _walled(kinds: np.ndarray) -> np.ndarray:
    """``(n, (W+2)·(H+2) + 1)``: each level's flat kinds and one wall past them, where :func:`_view_cells` sends
    the view cells outside the grid (MiniGrid's ``Grid.slice`` pads with ``Wall()``)."""
    n = len(kinds)
    return np.concatenate([kinds.reshape(n, -1), np.full((n, 1), WALL, dtype=kinds.dtype)], axis=1)


def view_tables(kinds: np.ndarray, *, see_through_walls: bool = True, agent_view_size: int = 5) -> np.ndarray:
    """Every observation image the agent can get, for a batch of levels of one size.

    Args:
        kinds: ``(n, W+2, H+2)`` the levels' :func:`cell_kinds`.
        see_through_walls: As in :class:`~dsage_ray.domains.maze.env.MazeEnv`.
        agent_view_size: As in MazeEnv.

    Returns:
        ``(n, W+2, H+2, 4, s, s, 3)`` uint8: the image MiniGrid returns in level ``m`` with the agent at grid
        ``(x, y)`` heading ``d``. The agent sits at view ``(s//2, s-1)`` looking toward ``j = 0``.
    """
    n, width, height = kinds.shape
    size = agent_view_size
    image_shape = (n, width, height, 4, size, size, 3)
    if see_through_walls:
        return _ENCODING[view_kinds(kinds, agent_view_size=size)].reshape(image_shape)
    view = _walled(kinds)[:, _view_cells(width, height, size)]
    # MiniGrid computes visibility before blanking the agent's own cell, on the cell as it is.
    visible = _visibility((view == WALL).reshape(-1, size, size)).reshape(view.shape)
    view[..., size // 2, size - 1] = EMPTY
    return np.where(visible[..., None], _ENCODING[view], np.uint8(0)).reshape(image_shape)


def view_kinds(kinds: np.ndarray, *, agent_view_size: int = 5) -> np.ndarray:
    """The cell kind (EMPTY, WALL, GOAL) under every view cell of every agent state, walls seen through.

    Args:
        kinds: ``(n, W+2, H+2)`` the levels' :func:`cell_kinds`.
        agent_view_size: As in MazeEnv.

    Returns:
        ``(n, (W+2)·(H+2)·4, s, s)``, states in ``[x, y, heading]`` order; the agent's own cell reads as empty
        (it carries nothing). :func:`view_tables` encodes these as MiniGrid images.
    """
    n, width, height = kinds.shape
    size = agent_view_size
    view = _walled(kinds)[:, _view_cells(width, height, size)]
    view[..., size // 2, size - 1] = EMPTY
    return view


def view_table(level: MazeLevel, *, see_through_walls: bool = True, agent_view_size: int = 5) -> np.ndarray:
    """:func:`view_tables` of one level: ``(W+2, H+2, 4, s, s, 3)`` uint8."""
    return view_tables(cell_kinds(level)[None], see_through_walls=see_through_walls,
                       agent_view_size=agent_view_size)[0]


#: With at least this many episodes per level (or without ``see_through_walls``), the simulator renders every view
#: of its levels once (:func:`view_tables`, about 0.3 ms per 16×16 level) and each step looks them up; with fewer,
#: each step gathers its views from the levels' cells, which costs a little more per step and nothing up front
#: (a one-episode screen of many levels).
TABLE_EPISODES = 4


class BatchedMazeSimulator:
    """Steps ``n`` episodes at once, on one level or on several of the same size; bit-identical to stepping
    ``n`` MazeEnvs.

    Episodes are independent: finished ones are not auto-reset; drop them with :meth:`keep`.

    Args:
        level: A valid level, or a sequence of valid levels of one size (:meth:`reset` says which level
            each episode plays; the default is the first).
        see_through_walls: As in :class:`~dsage_ray.domains.maze.env.MazeEnv`.
        agent_view_size: As in MazeEnv.
        max_steps: As in MazeEnv; default ``level.max_steps``.

    Attributes:
        positions: ``(n, 2)`` int64 grid ``(x, y)`` per episode (MiniGrid's ``agent_pos``).
        directions: ``(n,)`` int64 heading per episode (MiniGrid's ``agent_dir``).
        step_counts: ``(n,)`` int64 steps taken per episode.
        levels: The levels, in the order ``level_index`` counts them.
        level_index: ``(n,)`` int64 which of the levels each episode plays.
    """

    def __init__(
        self,
        level: MazeLevel | Sequence[MazeLevel],
        *,
        see_through_walls: bool = True,
        agent_view_size: int = 5,
        max_steps: int | None = None,
    ):
        levels = [level] if isinstance(level, MazeLevel) else list(level)
        if not levels:
            raise ValueError("BatchedMazeSimulator needs at least one level")
        if not all(each.valid for each in levels):
            raise ValueError("BatchedMazeSimulator needs a valid level (a start and a goal connected to each other)")
        if len({each.walls.shape for each in levels}) > 1:
            raise ValueError(f"the levels of one BatchedMazeSimulator must share a size, got "
                             f"{sorted({each.walls.shape for each in levels})}")
        self.levels = levels
        self.max_steps = int(max_steps if max_steps is not None else levels[0].max_steps)
        self._kinds = np.stack([cell_kinds(each) for each in levels])
        self._see_through_walls = see_through_walls
        self._view_size = agent_view_size
        self._views: np.ndarray | None = None
        self._walled_kinds = _walled(self._kinds)
        self._view_cells = _view_cells(*self._kinds.shape[1:], agent_view_size).reshape(-1, agent_view_size ** 2)
        self._starts = np.array([[each.start[1] + 1, each.start[0] + 1] for each in levels], dtype=np.int64)
        self.positions = np.zeros((0, 2), dtype=np.int64)
        self.directions = np.zeros(0, dtype=np.int64)
        self.step_counts = np.zeros(0, dtype=np.int64)
        self.level_index = np.zeros(0, dtype=np.int64)

    @property
    def num_episodes(self) -> int:
        return len(self.directions)

    def reset(self, directions: np.ndarray, level_index: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Starts ``len(directions)`` episodes, each at its level's start.

        Args:
            directions: ``(n,)`` initial headings in ``[0, 4)`` (MazeEnv draws them from its
                ``np_random``; here the caller does, so both can share the same draws).
            level_index: ``(n,)`` which level each episode plays; default all the first.

        Returns:
            The batched observation: ``image`` ``(n, s, s, 3)`` uint8 and ``direction`` ``(n,)`` int64.
        """
        directions = np.asarray(directions, dtype=np.int64).reshape(-1)
        if np.any((directions < 0) | (directions > 3)):
            raise ValueError(f"initial directions must lie in [0, 4), got {directions}")
        index = (np.zeros(len(directions), dtype=np.int64) if level_index is None
                 else np.asarray(level_index, dtype=np.int64).reshape(-1))
        if index.shape != directions.shape or np.any((index < 0) | (index >= len(self.levels))):
            raise ValueError(f"level_index must hold one index in [0, {len(self.levels)}) per episode")
        if self._views is None and not (self._see_through_walls and len(directions) < TABLE_EPISODES * len(self.levels)):
            self._views = view_tables(self._kinds, see_through_walls=self._see_through_walls,
                                      agent_view_size=self._view_size)
        self.directions = directions.copy()
        self.level_index = index.copy()
        self.positions = self._starts[index].copy()
        self.step_counts = np.zeros(len(directions), dtype=np.int64)
        return self._observe()

    def step(self, actions: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
        """Applies one action per episode.

        Returns:
            ``(obs, rewards (n,) float64, terminated (n,) bool, truncated (n,) bool)``.
        """
        actions = np.asarray(actions).reshape(-1)
        if actions.shape != self.directions.shape:
            raise ValueError(f"expected {self.num_episodes} actions, got {actions.shape[0]}")
        if np.any((actions < 0) | (actions >= NUM_ACTIONS)):
            raise ValueError(f"actions must lie in [0, {NUM_ACTIONS}), got {actions}")
        self.step_counts += 1
        ahead = self.positions + DIR_TO_VEC[self.directions]
        ahead_kind = self._kinds[self.level_index, ahead[:, 0], ahead[:, 1]]
        forward = actions == FORWARD
        moves = forward & (ahead_kind != WALL)
        self.positions[moves] = ahead[moves]
        terminated = forward & (ahead_kind == GOAL)
        # Same float64 arithmetic, in the same order, as MiniGridEnv._reward.
        rewards = np.where(terminated, 1 - 0.9 * (self.step_counts / self.max_steps), 0.0)
        self.directions = np.where(actions == LEFT, (self.directions - 1) % 4, self.directions)
        self.directions = np.where(actions == RIGHT, (self.directions + 1) % 4, self.directions)
        truncated = self.step_counts >= self.max_steps
        return self._observe(), rewards, terminated, truncated

    def keep(self, index: np.ndarray) -> None:
        """Keeps only the episodes at ``index`` (e.g. the unfinished ones), in that order."""
        self.positions = self.positions[index]
        self.directions = self.directions[index]
        self.step_counts = self.step_counts[index]
        self.level_index = self.level_index[index]

    def _observe(self) -> dict[str, np.ndarray]:
        if self._views is not None:
            image = self._views[self.level_index, self.positions[:, 0], self.positions[:, 1], self.directions]
        else:
            size = self._view_size
            state = (self.positions[:, 0] * self._kinds.shape[2] + self.positions[:, 1]) * 4 + self.directions
            view = self._walled_kinds[self.level_index[:, None], self._view_cells[state]]
            view[:, (size // 2) * size + size - 1] = EMPTY  # the agent's own cell reads as empty
            image = _ENCODING[view].reshape(len(state), size, size, 3)
        return {"image": image, "direction": self.directions.copy()}
