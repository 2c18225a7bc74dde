import numpy as np
import pytest
from PIL import Image

from dsage_ray.domains.maze.evaluate import evaluate
from dsage_ray.domains.maze.layout import load_layout
from dsage_ray.domains.maze.render import render_level

from .conftest import DATA, UniformRandomAgent


def test_render_writes_png_with_and_without_occupancy(tmp_path):
    level = load_layout(DATA / "labyrinth13.txt")
    result = evaluate(level, UniformRandomAgent(3), episodes=3, seed=0)
    path = tmp_path / "maze.png"
    data = render_level(level, result.occupancy, path, title="test")
    assert path.read_bytes() == data and data[:8] == b"\x89PNG\r\n\x1a\n"
    with_heat = Image.open(path)
    plain = render_level(level)
    assert with_heat.size[0] > 50 and plain != data


def test_render_rejects_wrong_occupancy_shape():
    level = load_layout(DATA / "small.txt")
    with pytest.raises(ValueError, match="occupancy"):
        render_level(level, np.zeros((3, 3)))
