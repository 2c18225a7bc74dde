import numpy as np
import pytest

from dsage_ray.domains.maze.evaluate import evaluate
from dsage_ray.domains.maze.layout import parse_layout
from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.measures import MEASURES, OBJECTIVES, get_measure, get_objective

from .conftest import UniformRandomAgent

EASY = "S.#.\n....\n.#.G\n"


def test_natural_ranges():
    assert get_measure("num_walls").natural_range(16, 16) == (0.0, 256.0)
    assert get_measure("mean_path_length").natural_range(16, 16) == (0.0, 648.0)
    assert get_measure("repeated_visits").natural_range(16, 16) == (0.0, 648.0)
    assert get_measure("explored_fraction").natural_range(16, 16) == (0.0, 1.0)
    assert get_measure("num_walls").natural_range(3, 5) == (0.0, 15.0)
    assert set(MEASURES) == {"num_walls", "mean_path_length", "explored_fraction", "repeated_visits",
                             "optimal_path_length", "success_rate"}


def test_measures_read_the_evaluation_and_lie_in_range():
    level = parse_layout(EASY)
    result = evaluate(level, UniformRandomAgent(3), episodes=20, seed=2)
    for name, measure in MEASURES.items():
        low, high = measure.natural_range(level.height, level.width)
        assert low <= measure.fn(result) <= high, name
    assert get_measure("num_walls").fn(result) == 2
    assert get_measure("mean_path_length").fn(result) == result.mean_path_length


def test_objectives():
    level = parse_layout(EASY)
    result = evaluate(level, UniformRandomAgent(3), episodes=20, seed=2)
    assert 0 < result.success_rate < 1
    assert get_objective("validity")(result) == 1.0
    assert get_objective("failure_rate")(result) == pytest.approx(1 - result.success_rate)
    excess = (result.episode_lengths - level.optimal_path_length) / (level.max_steps - level.optimal_path_length)
    assert get_objective("regret")(result) == pytest.approx(excess.mean())
    invalid = evaluate(MazeLevel.from_bitmap(np.ones((4, 4))), None, episodes=3)
    assert [OBJECTIVES[name](invalid) for name in ("validity", "failure_rate", "regret")] == [0.0, 0.0, 0.0]


def test_unknown_names():
    with pytest.raises(ValueError, match="known"):
        get_measure("nope")
    with pytest.raises(ValueError, match="known"):
        get_objective("nope")
