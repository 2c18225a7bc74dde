"""The Maze domain (SPEC: the Maze): wall bitmaps, a MiniGrid environment and its batched twin.

Importing the package registers ``"dsage_ray/Maze-v0"`` with gymnasium, so
``gymnasium.make("dsage_ray/Maze-v0", level=level)`` works.
"""

from dsage_ray.domains.maze.env import ENV_ID, MazeEnv, register_env
from dsage_ray.domains.maze.evaluate import MazeEvaluation, evaluate
from dsage_ray.domains.maze.generator import random_valid_level, random_valid_levels
from dsage_ray.domains.maze.layout import LayoutError, format_layout, load_layout, parse_layout
from dsage_ray.domains.maze.level import MazeLevel, furthest_pair
from dsage_ray.domains.maze.simulator import BatchedMazeSimulator

register_env()

__all__ = [
    "ENV_ID",
    "BatchedMazeSimulator",
    "LayoutError",
    "MazeEnv",
    "MazeEvaluation",
    "MazeLevel",
    "evaluate",
    "format_layout",
    "furthest_pair",
    "load_layout",
    "parse_layout",
    "random_valid_level",
    "random_valid_levels",
]
