"""The Maze's MiniGrid spaces, and the copy the RLlib network keeps (its class path is pinned by checkpoints)."""

from __future__ import annotations

from dsage_ray.agents import rllib_module
from dsage_ray.domains.maze.agents import constants


def test_the_rllib_networks_spaces_and_sizes_are_the_mazes():
    assert rllib_module.MAZE_OBSERVATION_SPACE == constants.OBSERVATION_SPACE
    assert rllib_module.MAZE_ACTION_SPACE == constants.ACTION_SPACE
    assert (rllib_module.NUM_OBJECT_KINDS, rllib_module.NUM_HEADINGS, rllib_module.VIEW_SIZE) == (
        constants.NUM_OBJECT_KINDS, constants.NUM_HEADINGS, constants.VIEW_SIZE)
