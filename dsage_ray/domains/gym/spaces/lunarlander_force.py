"""Setup hook of the shipped ``lunarlander_fault`` space: the lander's initial force is the level's.

An example of ``[env] setup`` (docs/GYM.md), for Mazouni et al.'s task (QD fault-diversity testing, AST 2024):
LunarLander pushes the lander with a random force in [-1000, 1000]² inside ``reset``, then steps the world once,
so no ``make``, ``reset`` or ``attr`` parameter reaches it. This hook resets the environment again, on the same
terrain (the same seed), with ``(force_x, force_y)`` in place of the random force, and returns the new first
observation. It swaps the environment's random generator for one that answers the two force draws with the level's
values and passes every other draw to the generator of the reset's seed, so everything else is as in a plain
reset with that seed. Checked against Gymnasium 1.x's ``LunarLander`` (``tests/domains/gym/test_fault_task.py``).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np


class _ForcedForce:
    """A random generator whose draws in ``[-bound, bound]`` are ``force``'s components, in order; others pass on."""

    def __init__(self, generator: np.random.Generator, *, force: tuple[float, float], bound: float) -> None:
        self.generator = generator
        self.force = [float(force[0]), float(force[1])]
        self.bound = bound
        self.used = 0

    def uniform(self, low: float = 0.0, high: float = 1.0, size: Any = None) -> Any:
        if size is None and (low, high) == (-self.bound, self.bound) and self.used < len(self.force):
            self.used += 1
            return self.force[self.used - 1]
        return self.generator.uniform(low, high, size)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.generator, name)


def initial_force(env: Any, values: Mapping[str, Any]) -> np.ndarray:
    """Replays the reset with the initial force ``(values["force_x"], values["force_y"])``; the first observation.

    Raises:
        RuntimeError: Not a Gymnasium LunarLander that draws its initial force as this hook expects.
    """
    from gymnasium.envs.box2d import lunar_lander
    from gymnasium.utils import seeding

    lander = env.unwrapped
    seed = getattr(lander, "np_random_seed", None)
    if not isinstance(lander, lunar_lander.LunarLander) or seed is None or seed < 0:
        raise RuntimeError("initial_force needs a Gymnasium LunarLander reset with a seed")
    forced = _ForcedForce(seeding.np_random(seed)[0], force=(values["force_x"], values["force_y"]),
                          bound=lunar_lander.INITIAL_RANDOM)
    lander.np_random = forced
    try:
        observation, _ = lander.reset()  # no seed: the reset keeps the generator set above
    finally:
        lander.np_random = forced.generator
    if forced.used != 2:
        raise RuntimeError(f"LunarLander drew {forced.used} initial force components, not 2: this Gymnasium's "
                           f"LunarLander is not the one initial_force was written for")
    return observation
