"""Setup hook of the ``bipedalwalker`` space: the walker's gravity and the weight of its hull, set after each reset.

BipedalWalker builds its Box2D world and bodies inside ``reset`` with fixed constants (gravity −10, hull density 5),
so no ``gym.make`` keyword or attribute reaches them; this hook sets them on the bodies of the episode just reset.
Gravity acts from the first step on (reset's own first observation came from one step at the default physics).
"""

from __future__ import annotations

from typing import Any, Mapping


def physics(env: Any, values: Mapping[str, Any]) -> None:
    """Sets the world's gravity and the hull's density (its mass, the legs unchanged) to the level's values."""
    walker = env.unwrapped
    walker.world.gravity = (0.0, float(values["gravity"]))
    for fixture in walker.hull.fixtures:
        fixture.density = float(values["hull_density"])
    walker.hull.ResetMassData()
