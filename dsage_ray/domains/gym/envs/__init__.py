"""Environments dsage_ray ships for the peers' tasks, registered with Gymnasium when the gym domain builds one.

``dsage_ray/TaxiMap-v0``: Taxi on any map drawing, with the faults a tester counts (:mod:`.taxi_map`); 200 steps,
as ``Taxi-v3``.
"""

from __future__ import annotations

import gymnasium

TAXI_MAP = "dsage_ray/TaxiMap-v0"


def register() -> None:
    """Registers the environments (once per process; a later call does nothing)."""
    if TAXI_MAP not in gymnasium.registry:
        gymnasium.register(TAXI_MAP, entry_point="dsage_ray.domains.gym.envs.taxi_map:TaxiMapEnv",
                           max_episode_steps=200)
