"""Taxi on a map of any size (``dsage_ray/TaxiMap-v0``), with the faults a tester counts.

Gymnasium's ``Taxi-v3`` is fixed to its 5 × 5 map. Mazouni et al. (QD fault-diversity testing, AST 2024) test a
Q-table agent on an 18 × 13 map with 11 locations, drawn as Taxi draws its own (``+--+`` borders, ``|`` walls,
``:`` open sides, a letter per location). This environment plays Taxi's rules on any such drawing:

* a state is ``((row * columns + column) * (locations + 1) + passenger) * locations + destination``, Taxi's own
  encoding (so ``Taxi-v3``'s tables fit the default map, and tables trained on a map of that drawing fit it);
* actions 0–3 move south, north, east, west; 4 picks up, 5 drops off;
* rewards: −1 a step, +20 for delivering the passenger (the episode ends), −10 for an illegal pick-up or drop-off;
  a drop-off at another location leaves the passenger there (−1), as in ``Taxi-v3``.

What a tester adds, in ``info``: ``crash`` (a move into a wall or the map's edge, which leaves the taxi where it
is), ``illegal`` (an action rewarded −10), ``fault`` (either), the moves made so far without and with the
passenger (``moves_empty``, ``moves_loaded``: Mazouni et al.'s behaviour), and the taxi's ``row`` and ``column``
(and ``rows_below`` it, for plots whose y axis points up).
With ``end_on_fault=True`` (the default) the episode ends at its first fault, as their executor stops it; with
``False`` and the default map it is ``Taxi-v3`` (not rainy), checked step by step in the tests.

The initial state is drawn as Taxi draws it, or given as ``reset(options=...)``: ``row``, ``column``,
``passenger`` (a location index, in the drawing's reading order) and ``destination``, or ``destination_offset`` in
``[1, locations - 1]`` (the destination is ``(passenger + offset) mod locations``, so every value of it is a
valid start: the passenger never starts at the destination).
"""

from __future__ import annotations

import pathlib
from typing import Any, Sequence

import gymnasium
import numpy as np
from gymnasium import spaces

#: The moves' (row, column) steps, in action order: south, north, east, west.
_MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1))
PICKUP, DROPOFF = 4, 5
#: Pixels per cell of the ``rgb_array`` frame.
_CELL = 24


def read_map(map_file: str | None) -> list[str]:
    """The drawing's lines: Gymnasium's own Taxi map when ``map_file`` is None.

    Raises:
        ValueError: Not a Taxi drawing (says why).
    """
    if map_file is None:
        from gymnasium.envs.toy_text.taxi import MAP

        return list(MAP)
    path = pathlib.Path(map_file)
    try:
        lines = [line.rstrip("\r\n") for line in path.read_text().splitlines() if line.strip()]
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"taxi map {str(path)!r}: cannot be read ({type(exc).__name__})") from None
    width = len(lines[0]) if lines else 0
    if (len(lines) < 3 or width < 3 or width % 2 == 0 or any(len(line) != width for line in lines)
            or not lines[0].startswith("+") or lines[-1] != lines[0]):
        raise ValueError(f"taxi map {str(path)!r}: not a Taxi drawing (equal lines of odd width between two "
                         f"'+---+' borders)")
    return lines


class TaxiMapEnv(gymnasium.Env):
    """Taxi's rules on the map ``map_file`` (module docstring).

    Args:
        map_file: A text file holding the drawing; None: Gymnasium's Taxi map.
        end_on_fault: End the episode at the first crash or illegal action.
        render_mode: ``"rgb_array"`` or None.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, map_file: str | None = None, end_on_fault: bool = True, render_mode: str | None = None) -> None:
        self.desc = np.asarray(read_map(map_file), dtype="c")
        #: How errors name the map.
        self.map_name = (f"map {str(map_file)!r}" if map_file is not None
                         else "Gymnasium's 5 x 5 Taxi map (no map_file given)")
        self.rows = self.desc.shape[0] - 2
        self.columns = (self.desc.shape[1] - 1) // 2
        self.locations = [(r, c) for r in range(self.rows) for c in range(self.columns)
                          if self.desc[1 + r, 2 * c + 1].isalpha()]
        if len(self.locations) < 2:
            raise ValueError(f"taxi map {map_file!r}: {len(self.locations)} location(s); Taxi needs two or more")
        self.in_taxi = len(self.locations)
        self.end_on_fault = bool(end_on_fault)
        self.render_mode = render_mode
        self.observation_space = spaces.Discrete(self.rows * self.columns * (self.in_taxi + 1) * self.in_taxi)
        self.action_space = spaces.Discrete(6)
        self.taxi = (0, 0)
        self.passenger = 0
        self.destination = 1
        self.moves = [0, 0]

    def encode(self, row: int, column: int, passenger: int, destination: int) -> int:
        """The state index of a taxi position, passenger location and destination (Taxi's encoding)."""
        return ((row * self.columns + column) * (self.in_taxi + 1) + passenger) * self.in_taxi + destination

    def decode(self, state: int) -> tuple[int, int, int, int]:
        """The taxi's row and column, the passenger's location and the destination of a state index."""
        state, destination = divmod(int(state), self.in_taxi)
        state, passenger = divmod(state, self.in_taxi + 1)
        row, column = divmod(state, self.columns)
        return row, column, passenger, destination

    def set_state(self, state: int) -> None:
        """Puts the episode in the state ``state`` (a trainer's or tester's hook), the move counts at zero."""
        row, column, self.passenger, self.destination = self.decode(state)
        self.taxi, self.moves = (row, column), [0, 0]

    def _state(self) -> int:
        return self.encode(*self.taxi, self.passenger, self.destination)

    def _info(self, *, crash: bool = False, illegal: bool = False) -> dict[str, Any]:
        return {"crash": crash, "illegal": illegal, "fault": crash or illegal, "moves_empty": self.moves[0],
                "moves_loaded": self.moves[1], "row": self.taxi[0], "column": self.taxi[1],
                "rows_below": self.rows - 1 - self.taxi[0]}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        options = dict(options or {})
        count = len(self.locations)
        row = options.pop("row", None)
        column = options.pop("column", None)
        passenger = options.pop("passenger", None)
        destination = options.pop("destination", None)
        offset = options.pop("destination_offset", None)
        if options:
            raise ValueError(f"TaxiMap reset options: unknown {sorted(options)} (row, column, passenger, "
                             f"destination, destination_offset)")
        row = int(self.np_random.integers(self.rows)) if row is None else int(row)
        column = int(self.np_random.integers(self.columns)) if column is None else int(column)
        passenger = int(self.np_random.integers(count)) if passenger is None else int(passenger)
        if offset is not None and destination is not None:
            raise ValueError("TaxiMap reset options: give destination or destination_offset, not both")
        if offset is not None:
            if not 1 <= int(offset) < count:
                raise ValueError(f"TaxiMap reset options: destination_offset {offset} is not in [1, {count - 1}] "
                                 f"on {self.map_name}")
            destination = (passenger + int(offset)) % count
        elif destination is None:
            destination = (passenger + 1 + int(self.np_random.integers(count - 1))) % count
        destination = int(destination)
        for name, value, size in (("row", row, self.rows), ("column", column, self.columns),
                                  ("passenger", passenger, count), ("destination", destination, count)):
            if not 0 <= value < size:
                raise ValueError(f"TaxiMap reset options: {name} {value} is not in [0, {size - 1}] on {self.map_name}")
        if passenger == destination:
            raise ValueError("TaxiMap reset options: the passenger starts at the destination")
        self.taxi, self.passenger, self.destination, self.moves = (row, column), passenger, destination, [0, 0]
        return self._state(), self._info()

    def _open(self, action: int) -> bool:
        """Whether the move ``action`` leaves the taxi's cell (no wall, not the map's edge)."""
        row, column = self.taxi
        if action == 0:
            return row < self.rows - 1
        if action == 1:
            return row > 0
        side = self.desc[1 + row, 2 * column + 2] if action == 2 else self.desc[1 + row, 2 * column]
        return side == b":"

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        action = int(action)
        if not 0 <= action < 6:
            raise ValueError(f"TaxiMap: action {action} is not in [0, 5]")
        reward, terminated, crash, illegal = -1.0, False, False, False
        if action < PICKUP:
            self.moves[int(self.passenger == self.in_taxi)] += 1
            if self._open(action):
                self.taxi = (self.taxi[0] + _MOVES[action][0], self.taxi[1] + _MOVES[action][1])
            else:
                crash = True
        elif action == PICKUP:
            if self.passenger < self.in_taxi and self.taxi == self.locations[self.passenger]:
                self.passenger = self.in_taxi
            else:
                reward, illegal = -10.0, True
        elif self.passenger == self.in_taxi and self.taxi == self.locations[self.destination]:
            self.passenger, reward, terminated = self.destination, 20.0, True
        elif self.passenger == self.in_taxi and self.taxi in self.locations:
            self.passenger = self.locations.index(self.taxi)
        else:
            reward, illegal = -10.0, True
        terminated = terminated or (self.end_on_fault and (crash or illegal))
        return self._state(), reward, terminated, False, self._info(crash=crash, illegal=illegal)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        return draw(self.desc, locations=self.locations, taxi=self.taxi, loaded=self.passenger == self.in_taxi,
                    passenger=None if self.passenger == self.in_taxi else self.locations[self.passenger],
                    destination=self.locations[self.destination])


def draw(desc: np.ndarray, *, locations: Sequence[tuple[int, int]], taxi: tuple[int, int], loaded: bool,
         passenger: tuple[int, int] | None, destination: tuple[int, int]) -> np.ndarray:
    """The map as an RGB image: grey locations, walls in black, the destination framed in magenta, the passenger a
    blue square, the taxi yellow (green when it carries the passenger)."""
    rows, columns = desc.shape[0] - 2, (desc.shape[1] - 1) // 2
    image = np.full((rows * _CELL + 1, columns * _CELL + 1, 3), 255, dtype=np.uint8)
    image[::_CELL, :] = image[:, ::_CELL] = 225  # the cells' outlines, light

    def cell(r: int, c: int, inset: int) -> tuple[slice, slice]:
        return (slice(r * _CELL + inset, (r + 1) * _CELL + 1 - inset),
                slice(c * _CELL + inset, (c + 1) * _CELL + 1 - inset))

    for r, c in locations:
        image[cell(r, c, 2)] = (190, 190, 190)
    image[cell(*destination, 1)] = (200, 0, 200)
    image[cell(*destination, 5)] = (190, 190, 190)
    if passenger is not None:
        image[cell(*passenger, 8)] = (30, 90, 220)
    image[cell(*taxi, 5)] = (40, 170, 40) if loaded else (240, 190, 0)
    for r in range(rows):
        for c in range(columns - 1):
            if desc[1 + r, 2 * c + 2] == b"|":
                x = (c + 1) * _CELL
                image[r * _CELL: (r + 1) * _CELL + 1, x - 2: x + 3] = 0
    image[:3, :] = image[-3:, :] = image[:, :3] = image[:, -3:] = 0  # the map's edge
    return image
