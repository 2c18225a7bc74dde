"""Objective, measures and occupancy of the A* agent on one level (SPEC: Mario).

- objective: mean ``getCompletionPercentage()`` over the runs;
- measures: ``sky_tiles`` (non-empty tiles in rows 0–8, a property of the level),
  ``mean_jumps`` and ``enemies_killed`` (means over the runs);
- occupancy: per-run tick counts at tile ``(⌊y/16⌋, ⌊x/16⌋)`` of Mario's position after each
  tick (``y`` at the feet, so a standing Mario counts in the row above the ground), positions
  outside the level dropped, averaged over the runs.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any, Callable, Sequence

import numpy as np

from dsage_ray.domains.mario.render import TILE_PX
from dsage_ray.domains.mario.simulator import EpisodeResult, MarioSimulator
from dsage_ray.domains.mario.tiles import sky_tiles, to_array, to_string


@dataclasses.dataclass
class MarioEvaluation:
    """Everything one evaluation of one level produced.

    Attributes:
        objective: Mean completion over the runs (0 when the evaluation failed).
        sky_tiles: Non-empty tiles in rows 0–8.
        mean_jumps: Mean ``getNumJumps()`` over the runs.
        enemies_killed: Mean ``getKillsTotal()`` over the runs.
        occupancy: ``(16, width)`` float32 expected ticks per tile per run.
        level: The level text.
        runs: Runs the evaluation stands for.
        episodes: The episodes actually played (one per run, or a single one when the
            iteration-count timer makes every run identical).
        failed: True when an episode raised in Java or hit the wall-clock timeout.
        error: The first such episode's message.
    """

    objective: float
    sky_tiles: int
    mean_jumps: float
    enemies_killed: float
    occupancy: np.ndarray
    level: str
    runs: int
    episodes: list[EpisodeResult]
    failed: bool = False
    error: str | None = None

    def episode_per_run(self) -> list[EpisodeResult]:
        """One episode per run (the deterministic single episode repeated)."""
        return self.episodes if len(self.episodes) == self.runs else self.episodes * self.runs

    @property
    def completion(self) -> list[float]:
        return [e.completion for e in self.episode_per_run()]

    @property
    def jumps(self) -> list[int]:
        return [e.jumps for e in self.episode_per_run()]

    @property
    def kills(self) -> list[int]:
        return [e.kills for e in self.episode_per_run()]

    @property
    def statuses(self) -> list[str]:
        return [e.status for e in self.episode_per_run()]

    @property
    def success_rate(self) -> float:
        """Fraction of the runs that reached the flag (status ``WIN``)."""
        return float(np.mean([status == "WIN" for status in self.statuses])) if self.episodes else 0.0

    def measure(self, name: str) -> float:
        """The named measure (see :data:`MEASURES`)."""
        try:
            return float(MEASURES[name](self))
        except KeyError:
            raise ValueError(f"unknown Mario measure {name!r} (known: {sorted(MEASURES)})") from None

    def to_dict(self, *, include_paths: bool = False) -> dict[str, Any]:
        """JSON-friendly summary (occupancy as nested lists; paths only when asked)."""
        out: dict[str, Any] = {
            "objective": self.objective,
            "sky_tiles": self.sky_tiles,
            "mean_jumps": self.mean_jumps,
            "enemies_killed": self.enemies_killed,
            "runs": self.runs,
            "episodes_played": len(self.episodes),
            "completion": self.completion,
            "success_rate": self.success_rate,
            "jumps": self.jumps,
            "kills": self.kills,
            "status": self.statuses,
            "ticks": [e.ticks for e in self.episode_per_run()],
            "search_iterations": [e.search_iterations for e in self.episode_per_run()],
            "deterministic": all(e.deterministic for e in self.episodes),
            "wall_s": sum(e.wall_s for e in self.episodes),
            "failed": self.failed,
            "error": self.error,
            "level": self.level,
            "occupancy": self.occupancy.round(4).tolist(),
        }
        if include_paths:
            out["paths"] = [e.path.tolist() for e in self.episodes]
        return out

    def to_json(self, *, include_paths: bool = False, indent: int | None = None) -> str:
        # NaN is not JSON; a failed episode's completion is reported as null.
        def clean(v: Any) -> Any:
            if isinstance(v, float) and not math.isfinite(v):
                return None
            if isinstance(v, list):
                return [clean(x) for x in v]
            return v

        return json.dumps({k: clean(v) for k, v in self.to_dict(include_paths=include_paths).items()}, indent=indent)


#: Measure name → how it is read off an evaluation.
MEASURES: dict[str, Callable[[MarioEvaluation], float]] = {
    "sky_tiles": lambda e: e.sky_tiles,
    "mean_jumps": lambda e: e.mean_jumps,
    "enemies_killed": lambda e: e.enemies_killed,
}


def occupancy_grid(paths: Sequence[np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """Per-run tick counts at each tile, averaged over ``paths`` (one ``(ticks, 2)`` array per run)."""
    grid = np.zeros(shape, dtype=np.float64)
    for path in paths:
        if len(path) == 0:
            continue
        cols = np.floor(path[:, 0] / TILE_PX).astype(np.int64)
        rows = np.floor(path[:, 1] / TILE_PX).astype(np.int64)
        inside = (rows >= 0) & (rows < shape[0]) & (cols >= 0) & (cols < shape[1])
        np.add.at(grid, (rows[inside], cols[inside]), 1.0)
    return (grid / max(len(paths), 1)).astype(np.float32)


def evaluate_level(level: np.ndarray | str | Sequence[str], *, simulator: MarioSimulator, runs: int = 5,
                   replay_deterministic: bool = False) -> MarioEvaluation:
    """Plays ``runs`` A* episodes on a level and summarises them.

    With the iteration-count timer an episode is a pure function of the level, so one episode
    stands for all ``runs`` (identical results; see the repeatability tests) unless
    ``replay_deterministic`` asks to play them all anyway.

    Raises:
        LevelError: If the level is invalid.
    """
    if runs < 1:
        raise ValueError(f"runs must be positive, got {runs}")
    tiles = to_array(level)
    text = to_string(tiles)
    to_play = 1 if simulator.deterministic and not replay_deterministic else runs
    episodes: list[EpisodeResult] = []
    for _ in range(to_play):
        episode = simulator.play(tiles)
        if not math.isfinite(episode.completion) and episode.ok:
            # An exit in column 0 makes the framework divide by zero; Mario never moved toward it.
            episode.completion = 0.0
        episodes.append(episode)
        if not episode.ok:
            break
    bad = next((e for e in episodes if not e.ok), None)
    evaluation = MarioEvaluation(
        objective=0.0, sky_tiles=sky_tiles(tiles), mean_jumps=0.0, enemies_killed=0.0,
        occupancy=np.zeros(tiles.shape, dtype=np.float32), level=text, runs=runs, episodes=episodes,
        failed=bad is not None, error=None if bad is None else f"{bad.status}: {bad.error}",
    )
    if bad is None:
        per_run = evaluation.episode_per_run()
        evaluation.objective = float(np.mean([e.completion for e in per_run]))
        evaluation.mean_jumps = float(np.mean([e.jumps for e in per_run]))
        evaluation.enemies_killed = float(np.mean([e.kills for e in per_run]))
        evaluation.occupancy = occupancy_grid([e.path for e in per_run], tiles.shape)
    return evaluation
