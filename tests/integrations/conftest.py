"""Fakes for the audit-during-training tests: a series that records its calls, and a tiny Maze collection."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from tests.scripts import import_script

REPO_ROOT = Path(__file__).resolve().parents[2]
SCRIPT = REPO_ROOT / "experiments" / "train_maze_agent.py"


@dataclasses.dataclass(frozen=True)
class FakeRecord:
    """What the callbacks read of a :class:`~dsage_ray.audit.series.SeriesRecord`."""

    label: str
    agent: str
    step: int | None
    error: str | None = None
    suite_success_rate: float | None = 0.5

    def scalars(self) -> dict[str, float]:
        out = {"audit/new_failures": 2.0, "audit/wall_time": 0.01}
        if self.suite_success_rate is not None:
            out["audit/suite_success_rate"] = self.suite_success_rate
        return out


class FakeSeries:
    """Records ``audit`` calls; ``fail`` raises that exception, ``error`` returns records with that error,
    ``load`` loads the agent spec first (so an unreadable checkpoint raises as the real series would)."""

    def __init__(self, *, fail: BaseException | None = None, error: str | None = None, load: bool = False,
                 **settings: Any) -> None:
        self.fail, self.error, self.load = fail, error, load
        self.settings = settings
        self.calls: list[tuple[str, str | None, int | None]] = []
        self.agents: list[Any] = []

    def audit(self, agent: str, *, label: str | None = None, step: int | None = None) -> FakeRecord:
        self.calls.append((agent, label, step))
        if self.fail is not None:
            raise self.fail
        if self.load:
            from dsage_ray.domains.maze.agents import load_maze_agent

            self.agents.append(load_maze_agent(agent))
        return FakeRecord(label=label or agent, agent=agent, step=step, error=self.error,
                          suite_success_rate=None if self.error else 0.5)


class FakeWriter:
    """A SummaryWriter stand-in: ``(tag, value, step)`` per scalar."""

    def __init__(self) -> None:
        self.scalars: list[tuple[str, float, int | None]] = []

    def add_scalar(self, tag: str, value: float, step: int | None = None) -> None:
        self.scalars.append((tag, value, step))

    def flush(self) -> None:
        pass


@pytest.fixture
def script(monkeypatch):
    """``experiments/train_maze_agent.py`` imported as a module (kept in ``sys.modules`` for tyro)."""
    return import_script(SCRIPT, monkeypatch)


def write_collection(folder: Path, levels, *, domain: str = "maze", success: float = 0.0) -> Path:
    """A minimal ``collection.json`` (format v2) with ``levels`` (MazeLevel) as level files."""
    from dsage_ray.domains.maze.layout import format_layout

    (folder / "levels").mkdir(parents=True)
    entries = []
    for i, level in enumerate(levels):
        (folder / "levels" / f"level_{i:04d}.txt").write_text(format_layout(level))
        entries.append({"id": i, "level_file": f"levels/level_{i:04d}.txt", "image_file": f"levels/level_{i:04d}.png",
                        "objective": 1.0 - success, "success_rate": success, "seed": 100 + i, "episodes": 5,
                        "measures": {"num_walls": float(level.num_walls),
                                     "optimal_path_length": float(level.optimal_path_length)},
                        "reproduce": "true"})
    (folder / "collection.json").write_text(json.dumps({
        "format": "dsage_ray.collection.v2", "domain": domain, "agent": "builtin:random", "reference": None,
        "objective": "failure_rate", "measures": ["num_walls", "optimal_path_length"],
        "measure_ranges": [[0, 256], [0, 256]], "archive_dims": [16, 16], "levels": entries}))
    return folder
