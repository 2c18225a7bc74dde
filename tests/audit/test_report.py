"""report.html without a browser: self-contained, the summary numbers, v1 and regression collections, pictures."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
from PIL import Image

from dsage_ray.audit import collection as collection_module
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.audit.report import WORST_SHOWN, write_compare_report, write_report, zoom_window
from dsage_ray.audit.summary import failure_summary

AGENT, REFERENCE = "builtin:wall_follower", "builtin:random"


def _png(colour: tuple[int, int, int]) -> bytes:
    buffer = io.BytesIO()
    Image.new("RGB", (6, 6), colour).save(buffer, format="PNG")
    return buffer.getvalue()


def make_collection(folder: Path, *, levels: int = 15, regression: bool = False, v1: bool = False) -> Path:
    """A Maze collection written by hand: success rates cycle 0, 0.25, ..., 1; measures spread over a corner.

    v2 by default (the collection module's current format); ``v1`` writes the old Maze-only keys
    (``layout_file``, no ``reproduce``, no ``domain``/``reference``).
    """
    (folder / "levels").mkdir(parents=True)
    entries = []
    for i in range(levels):
        success = (i % 5) / 4
        stem = f"levels/level_{i:04d}"
        (folder / f"{stem}.txt").write_text("S..\n.#.\n..G\n")
        (folder / f"{stem}.png").write_bytes(_png((255, 40 * (i % 6), 0)))
        entry = {
            "id": i, "image_file": f"{stem}.png", "objective": 1 - success, "success_rate": success,
            "measures": {"num_walls": 100.0 + 3 * i, "optimal_path_length": 20.0 + (i % 7)},
            "num_walls": 100 + 3 * i, "optimal_path_length": 20 + (i % 7), "mean_path_length": 50.5 + i,
            "seed": 1000 + i, "episodes": 4, "search_objective": 0.9, "search_measures": {},
        }
        if v1:
            entry.update(layout_file=f"{stem}.txt", layout="S..\n.#.\n..G\n")
        else:
            entry.update(level_file=f"{stem}.txt", layout_file=f"{stem}.txt",
                         reproduce=f"dsage-ray maze eval --agent {AGENT} --layout {folder}/{stem}.txt --episodes 4 "
                                   f"--seed {1000 + i}")
        if regression:
            reference_success = min(1.0, success + (0.5 if i % 3 else 0.0))
            entry["reference"] = {"success_rate": reference_success, "mean_path_length": 30.25 + i, "seed": 1000 + i}
            entry["regression"] = reference_success - success
            entry["objective"] = (1 + entry["regression"]) / 2
        entries.append(entry)
    if regression:
        entries.sort(key=lambda e: -e["regression"])
    data = {
        "format": "dsage_ray.collection.v1" if v1 else collection_module.FORMAT,
        "agent": AGENT, "objective": "regression" if regression else "failure_rate",
        "measures": ["num_walls", "optimal_path_length"], "measure_ranges": [[0.0, 256.0], [0.0, 256.0]],
        "archive_dims": [256, 256], "episodes": 4, "run_seed": 7, "search_dir": "/somewhere/search",
        "search_elites": levels, "search_invalid_elites": 0,
        "config": {"preset": "tiny", "budget": 150}, "created": "2026-01-02 03:04:05", "levels": entries,
    }
    if v1:
        data["see_through_walls"] = False
    else:
        data.update(domain="maze", reference=REFERENCE if regression else None)
    (folder / "collection.json").write_text(json.dumps(data))
    return folder


def _links(page: str) -> list[str]:
    return re.findall(r"""(?:src|href)=['"]([^'"]+)['"]""", page)


def test_report_is_self_contained(tmp_path):
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    links = _links(page)
    assert not [link for link in links if re.match(r"(?i)(https?:)?//", link)], "no network"
    files = [link for link in links if not link.startswith("data:")]
    assert files and all((folder / link).is_file() for link in files), "every link is the collection's own file"
    # Embedded: the two heatmaps and the worst levels' pictures; every other picture is a link.
    assert page.count("src='data:image/png;base64,") == 2 + min(WORST_SHOWN, 15)
    assert "<script>" in page and "<style>" in page


def test_summary_numbers_and_metadata_appear(tmp_path):
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    summary = failure_summary(load_collection(folder))
    assert summary["never_solved"] == 3 and summary["with_failures"] == 12
    tiles = dict((label, value) for value, label in
                 re.findall(r"<div class='stat'><b>([^<]*)</b><span>([^<]*)</span>", page))
    assert tiles["levels"] == "15"
    assert tiles["never solved"] == str(summary["never_solved"])
    assert tiles["with at least one failure"] == str(summary["with_failures"])
    assert tiles["archive cells with failure rate ≥ 0.5"] == str(summary["failure_cells"])
    assert tiles["mean success rate of the worst 10% (CVaR)"] == f"{summary['cvar10']:.3f}"
    for text in ("tiny", "150 real evaluations", "/somewhere/search", "failure_rate", "2026-01-02 03:04:05"):
        assert text in page, text


def test_table_has_every_level_worst_first_with_its_command(tmp_path):
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    body = page.split("id='levels'", 1)[1].split("<tbody>", 1)[1].split("</tbody>", 1)[0]
    rows = re.findall(r"<tr data-s='([^']*)' data-m='([^']*)'>(.*?)</tr>", body)
    assert len(rows) == 15
    assert [re.search(r"<td>(\d+)</td>", r[2]).group(1) for r in rows] == [str(i) for i in range(15)]
    assert rows[3][:2] == ("0.75", "109.0 23.0")
    assert "--seed 1003</code>" in rows[3][2] and "href='levels/level_0003.png'" in rows[3][2]


def test_v1_collection_renders_with_rebuilt_commands(tmp_path):
    folder = make_collection(tmp_path / "old", levels=4, v1=True)
    page = write_report(folder).read_text()
    assert "<dt>domain</dt><dd>maze</dd>" in page and "<dt>reference</dt><dd>none</dd>" in page
    for i in range(4):
        assert re.search(rf"dsage-ray maze eval --agent {AGENT} --layout \S*levels/level_000{i}\.txt "
                         rf"--episodes 4 --seed {1000 + i} --no-see-through-walls", page), i


def test_regression_collection_shows_both_agents(tmp_path):
    folder = make_collection(tmp_path / "r", levels=9, regression=True)
    # A reference picture, where the builder keeps one, sits beside the agent's.
    data = json.loads((folder / "collection.json").read_text())
    data["levels"][0]["reference"]["image_file"] = "levels/level_0005.png"
    (folder / "collection.json").write_text(json.dumps(data))
    page = write_report(folder).read_text()
    assert f"Regression audit of {AGENT} against {REFERENCE}" in page
    first_card = page.split("<div class='card'>")[1]
    assert first_card.count("src='data:image/png") == 2
    assert f"<figcaption>{AGENT}</figcaption>" in first_card and f"<figcaption>{REFERENCE}</figcaption>" in first_card
    # Each card: a column per agent, and both commands with the same seed.
    assert page.count(f"<th title='{AGENT}'>agent</th><th title='{REFERENCE}'>reference</th>") == 9
    for card in page.split("<h2>Per-region")[0].split("<div class='card'>")[1:]:
        commands = [re.sub(r"</?span>", "", code) for code in re.findall(r"<code class='cmd'>(.*?)</code>", card)]
        assert len(commands) == 2
        assert [c.replace(REFERENCE, AGENT) for c in commands[1:]] == commands[:1]
        assert f"--agent {REFERENCE} --layout" in commands[1]
    for header in ("reference success rate", "reference mean path length", "regression"):
        assert f">{header}</th>" in page, header
    assert "id='regressed'" in page
    summary = failure_summary(load_collection(folder))
    assert f"<b>{summary['regressed']}</b><span>levels where the agent does worse" in page


def test_mario_collection_renders_its_own_numbers(tmp_path):
    folder = make_collection(tmp_path / "m", levels=5)
    data = json.loads((folder / "collection.json").read_text())
    data.update(domain="mario", agent="astar", objective="incompletion", measures=["sky_tiles", "mean_jumps"],
                measure_ranges=[[0.0, 150.0], [0.0, 100.0]], archive_dims=[150, 100])
    for i, entry in enumerate(data["levels"]):
        for key in ("layout_file", "num_walls", "optimal_path_length", "mean_path_length"):
            del entry[key]
        entry.update(measures={"sky_tiles": 40.0 + i, "mean_jumps": 3.0 * i}, completion=0.2 * i, jumps=3 * i,
                     reproduce=f"dsage-ray mario eval --level {folder}/levels/level_{i:04d}.txt --runs 4")
    (folder / "collection.json").write_text(json.dumps(data))
    page = write_report(folder).read_text()
    assert "<dt>domain</dt><dd>mario</dd>" in page and ">completion</th>" in page and ">sky_tiles</th>" in page
    assert "mean path length" not in page and "maze eval" not in page
    assert re.sub(r"</?span>", "", page).count("dsage-ray mario eval --level") == 5 + 5  # cards + table


def test_empty_collection_renders(tmp_path):
    folder = make_collection(tmp_path / "e", levels=0)
    page = write_report(folder).read_text()
    assert "All 0 levels" in page and "<b>n/a</b>" in page


def test_zoom_window_pads_the_occupied_cells():
    assert zoom_window(100, 120, 256) == (97, 123)  # 10 % of 21 cells, rounded up: 3
    assert zoom_window(0, 4, 256) == (0, 6)  # at least 2 cells, clipped at the edge
    assert zoom_window(250, 255, 256) == (248, 255)


def test_compare_page_is_sortable(tmp_path):
    folder = make_collection(tmp_path / "c", levels=3)
    rows = [{"id": i, "layout_file": f"levels/level_{i:04d}.txt", "seed": i, "episodes": 4, "success_a": 1.0,
             "success_b": 0.5 * i, "path_a": 10.0, "path_b": 12.0, "verdict": "worse" if i < 2 else "same"}
            for i in range(3)]
    comparison = {"agent_a": AGENT, "agent_b": REFERENCE, "levels": rows, "episodes_note": "4 episodes",
                  "summary": {"levels": 3, "threshold": 0.1, "success_a": 1.0, "success_b": 0.5, "path_a": 10.0,
                              "path_b": 12.0, "solved_a": 3, "solved_b": 1, "b_worse": 2, "b_better": 0}}
    path = write_compare_report(tmp_path / "page" / "compare.html", comparison, collection_dir=folder,
                                images={0: _png((0, 0, 0))})
    page = path.read_text()
    assert "class='sortable'" in page and page.count("<tr class='worse'>") == 2
    assert all((path.parent / link).is_file() for link in _links(page) if not link.startswith("data:"))


def test_maze_picture_shared_scale_and_colours():
    from matplotlib.colors import to_rgb

    from dsage_ray.domains.maze.layout import parse_layout
    from dsage_ray.domains.maze.render import WALL_COLOUR, _visit_cmap, render_level

    level = parse_layout("S..#\n.#..\n...G\n")
    occupancy = np.zeros((3, 4))
    occupancy[0, :3] = [1.0, 2.0, 4.0]
    own = render_level(level, occupancy)
    assert render_level(level, occupancy, occupancy_max=4.0) == own  # None = the level's own maximum
    assert render_level(level, occupancy, occupancy_max=40.0) != own
    # The most-visited colour is a bright, saturated red; the walls a dark grey (inferno_r's top, near-black, fails).
    top, wall = np.array(_visit_cmap()(1.0)[:3]), np.array(to_rgb(WALL_COLOUR))
    assert top[0] > 0.7 and top.max() - top.min() > 0.5
    assert wall.max() < 0.25 and wall.max() - wall.min() < 0.05


def test_mario_picture_shared_scale_and_title():
    from dsage_ray.domains.mario.render import level_png, render_level

    level = np.zeros((16, 10), dtype=np.int64)  # all sky
    occupancy = np.zeros((16, 10), dtype=np.float32)
    occupancy[5, :] = 4.0
    own = render_level(level, scale=2, occupancy=occupancy)
    shared = render_level(level, scale=2, occupancy=occupancy, occupancy_max=100.0)
    sky = render_level(level, scale=2)
    tint = lambda image: np.abs(image[10, 0].astype(int) - sky[10, 0].astype(int)).sum()  # noqa: E731
    assert tint(shared) < tint(own)  # a larger shared maximum tints this level's visits less
    assert (render_level(level, scale=2, occupancy=occupancy, occupancy_max=4.0) == own).all()
    titled = Image.open(io.BytesIO(level_png(level, scale=2, title="#0: completion 0.40")))
    assert titled.size[0] > 20 and titled.size[1] > 32  # the figure around the 20 x 32 image
