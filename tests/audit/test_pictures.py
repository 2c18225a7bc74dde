"""The pictures a report shows can be read at the size it shows them: each text is at least ``MIN_TEXT_PX`` tall on
the page when the picture is ``PICTURE_MIN_WIDTH`` wide (a card on a 390 px phone), and no two texts overlap.

The texts are the ones matplotlib draws, recorded as it draws them (:func:`drawn_texts`); their size on the page
is their size in the PNG times the page's scale (shown width / PNG width). ``test_report_browser.py`` measures the
shown width in Chromium.
"""

from __future__ import annotations

import io
import itertools
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest
from PIL import Image

from dsage_ray.audit.report import PICTURE_MIN_WIDTH, heatmap_pngs

#: The smallest text on the page, in CSS pixels (the font's size, as a browser's ``font-size``).
MIN_TEXT_PX = 11


@dataclass
class Text:
    text: str
    px: float  # font size in the PNG's pixels
    box: tuple[float, float, float, float]  # x0, y0, x1, y1 in the figure's pixels


@dataclass
class Picture:
    png: bytes
    texts: list[Text]
    size: tuple[float, float] = (float("inf"), float("inf"))  # the figure's, in pixels

    @property
    def width(self) -> int:
        return Image.open(io.BytesIO(self.png)).size[0]

    def smallest_text_on_page(self, shown_width: float) -> float:
        """The smallest font size on the page, in CSS pixels, when the picture is shown ``shown_width`` wide."""
        return min(t.px for t in self.texts) * shown_width / self.width

    def overlapping(self) -> list[tuple[str, str]]:
        """The pairs of texts whose boxes overlap by more than a pixel."""
        def overlap(a: Text, b: Text) -> bool:
            return (min(a.box[2], b.box[2]) - max(a.box[0], b.box[0]) > 1
                    and min(a.box[3], b.box[3]) - max(a.box[1], b.box[1]) > 1)

        return [(a.text, b.text) for a, b in itertools.combinations(self.texts, 2) if overlap(a, b)]

    def cut(self) -> list[str]:
        """The texts that reach past the figure's edge (the picture would show them cut)."""
        width, height = self.size
        return [t.text for t in self.texts if t.box[0] < -1 or t.box[1] < -1 or t.box[2] > width + 1
                or t.box[3] > height + 1]


def drawn_figures(draw: Callable[[], object]) -> tuple[object, list[tuple[list[Text], tuple[float, float]]]]:
    """Calls ``draw`` and records the texts matplotlib draws meanwhile: ``draw``'s result and, for each figure
    drawn (in the order they were drawn), its texts and its size in pixels."""
    from matplotlib.backends.backend_agg import RendererAgg

    figures: dict[int, tuple[list[Text], tuple[float, float]]] = {}
    original = RendererAgg.draw_text

    def record(renderer, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if s.strip() and mtext is not None:
            box = mtext.get_window_extent(renderer)
            figure = mtext.get_figure(root=True)
            texts, _ = figures.setdefault(id(figure), ([], (renderer.width, renderer.height)))
            texts.append(Text(s, prop.get_size_in_points() * renderer.dpi / 72, (box.x0, box.y0, box.x1, box.y1)))
        return original(renderer, gc, x, y, s, prop, angle, ismath=ismath, mtext=mtext)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(RendererAgg, "draw_text", record)
        result = draw()
    return result, list(figures.values())


def drawn_texts(draw: Callable[[], bytes]) -> Picture:
    """The PNG ``draw`` returns and the texts of its figure."""
    png, figures = drawn_figures(draw)
    assert len(figures) == 1, "one figure"
    return Picture(png, *figures[0])


def maze_picture() -> Picture:
    """A Maze level of the audits' size (16 x 16) with visits and a title, as a collection draws it."""
    from dsage_ray.domains.maze.generator import random_valid_levels
    from dsage_ray.domains.maze.render import render_level

    level = random_valid_levels(1, seed=0)[0]
    occupancy = np.random.default_rng(0).gamma(0.5, 20.0, size=level.walls.shape) * ~level.walls
    return drawn_texts(lambda: render_level(level, occupancy, title="level #12", occupancy_max=88.25))


def mario_picture() -> Picture:
    from dsage_ray.domains.mario.render import level_png

    level = np.zeros((16, 56), dtype=np.int64)
    level[14:] = 11  # ground
    occupancy = np.zeros((16, 56))
    occupancy[13, :30] = 5.0
    return drawn_texts(lambda: level_png(level, occupancy=occupancy, title="level #12"))


def gym_picture() -> Picture:
    from dsage_ray.domains.gym.render import level_picture
    from dsage_ray.domains.gym.space import build_space, read_space_tables

    tables, source = read_space_tables("cartpole")
    space = build_space(tables, source=source)
    values = space.values(np.zeros(len(space.params)))
    occupancy = np.random.default_rng(0).random(space.occupancy_shape)
    return drawn_texts(lambda: level_picture(space, values, occupancy=occupancy / occupancy.sum(),
                                             title="level #12"))


def heatmap_pictures(folder) -> list[Picture]:
    """The two heatmaps of a made collection (``test_report.make_collection``) in ``folder``."""
    from dsage_ray.audit.collection_file import load_collection

    from .test_report import make_collection

    collection = load_collection(make_collection(folder, levels=40))
    pngs, figures = drawn_figures(lambda: heatmap_pngs(collection))
    return [Picture(pngs[name], *figure) for name, figure in zip(("zoomed", "full"), figures, strict=True)]


@pytest.mark.parametrize("make", [maze_picture, mario_picture, gym_picture], ids=["maze", "mario", "gym"])
def test_level_pictures_are_legible_where_the_report_shows_them(make):
    picture = make()
    assert picture.smallest_text_on_page(PICTURE_MIN_WIDTH) >= MIN_TEXT_PX, [(t.text, t.px) for t in picture.texts]
    assert picture.overlapping() == [] and picture.cut() == []


def test_heatmaps_are_legible_where_the_report_shows_them(tmp_path):
    for picture in heatmap_pictures(tmp_path / "c"):
        assert picture.smallest_text_on_page(PICTURE_MIN_WIDTH) >= MIN_TEXT_PX
        assert picture.overlapping() == [] and picture.cut() == []


def test_the_maze_colour_bar_numbers_keep_apart():
    """Its square-root scale crowds the top: the bar names only none, a quarter of the top (its middle) and the
    top."""
    picture = maze_picture()
    numbers = [t.text for t in picture.texts if t.text.replace(".", "").isdigit()]
    assert {"0", "22.1", "88.2"} <= set(numbers)
