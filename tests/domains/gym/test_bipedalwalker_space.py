"""The shipped ``bipedalwalker`` space: its setup hook sets the level's gravity and hull weight on the bodies reset
built, and its nominal level is the walker as registered."""

import numpy as np
import pytest

from dsage_ray.domains.gym.simulator import make_env, reset_env
from dsage_ray.domains.gym.space import build_space, read_space_tables

pytest.importorskip("Box2D")


@pytest.fixture
def space():
    tables, source = read_space_tables("bipedalwalker")
    return build_space(tables, source=source)


def test_the_hook_sets_gravity_and_hull_density_each_reset(space):
    values = {"gravity": -15.0, "hull_density": 9.0}
    env = make_env(space, values)
    try:
        reset_env(env, space, values, seed=0)
        walker = env.unwrapped
        assert tuple(walker.world.gravity) == pytest.approx((0.0, -15.0))
        heavy = walker.hull.mass
        light = {"gravity": -10.0, "hull_density": 5.0}
        reset_env(env, space, light, seed=0)
        assert tuple(env.unwrapped.world.gravity) == pytest.approx((0.0, -10.0))
        assert env.unwrapped.hull.mass == pytest.approx(heavy * 5.0 / 9.0)
    finally:
        env.close()


def test_the_nominal_level_is_the_registered_walker(space):
    assert space.nominal == {"gravity": -10.0, "hull_density": 5.0}
    box_centre = space.values(np.zeros(len(space.params)))
    assert box_centre["gravity"] == pytest.approx(-10.5) and box_centre["hull_density"] == pytest.approx(6.25)
