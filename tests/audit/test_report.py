"""report.html without a browser: self-contained, the summary numbers, regression collections, pictures."""

from __future__ import annotations

import base64
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from dsage_ray.audit import collection as collection_module
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.audit.report import WORST_SHOWN, write_compare_report, write_report
from dsage_ray.qd.archives import zoom_window
from dsage_ray.audit.summary import failure_summary

AGENT, REFERENCE = "builtin:wall_follower", "builtin:random"


def _png(colour: tuple[int, int, int]) -> bytes:
    buffer = io.BytesIO()
    Image.new("RGB", (6, 6), colour).save(buffer, format="PNG")
    return buffer.getvalue()


def make_collection(folder: Path, *, levels: int = 15, regression: bool = False) -> Path:
    """A Maze collection written by hand: success rates cycle 0, 0.25, ..., 1; measures spread over a corner."""
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
        "format": collection_module.FORMAT,
        "agent": AGENT, "objective": "regression" if regression else "failure_rate",
        "measures": ["num_walls", "optimal_path_length"], "measure_ranges": [[0.0, 256.0], [0.0, 256.0]],
        "archive_dims": [256, 256], "episodes": 4, "run_seed": 7, "search_dir": "/somewhere/search",
        "search_elites": levels, "search_invalid_elites": 0,
        "config": {"preset": "tiny", "budget": 150}, "created": "2026-01-02 03:04:05", "levels": entries,
        "domain": "maze", "reference": REFERENCE if regression else None,
    }
    (folder / "collection.json").write_text(json.dumps(data))
    return folder


def _links(page: str) -> list[str]:
    return re.findall(r"""(?:src|href)=['"]([^'"]+)['"]""", page)


def test_report_is_self_contained(tmp_path):
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    links = _links(page)
    assert not [link for link in links if re.match(r"(?i)(https?:)?//", link)], "no network"
    files = [link for link in links if not link.startswith(("data:", "#"))]
    assert files and all((folder / link).is_file() for link in files), "every link is the collection's own file"
    anchors = [link[1:] for link in links if link.startswith("#")]
    assert anchors and all(f"id='{a}'" in page for a in anchors), "every in-page link has its target"
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
    rows = re.findall(r"<tr id='level-(\d+)' data-s='([^']*)' data-m='([^']*)'>(.*?)</tr>", body)
    assert len(rows) == 15
    assert [re.search(r"<td>(\d+)</td>", r[3]).group(1) for r in rows] == [r[0] for r in rows] == [
        str(i) for i in range(15)]
    assert rows[3][1:3] == ("0.75", "109.0 23.0")
    assert "href='levels/level_0003.png'" in rows[3][3] and ">levels/level_0003.txt</a>" in rows[3][3]
    # The copy button's command names the level file relative to the collection folder.
    assert re.search(r"data-cmd='dsage-ray maze eval [^']*--layout levels/level_0003\.txt [^']*--seed 1003'",
                     rows[3][3])


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
    for header in ("reference failure rate", "reference mean path length", "regression"):
        assert f">{header}</button></th>" in page, header
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
    assert "<dt>domain</dt><dd>mario</dd>" in page
    assert ">completion</button></th>" in page and ">sky_<wbr>tiles</button></th>" in page
    assert "mean path length" not in page and "maze eval" not in page and "step limit" not in page
    cards = page.split("<h2>Per-region")[0]
    assert re.sub(r"</?span>", "", cards).count("dsage-ray mario eval --level levels/") == 5
    assert page.count("data-cmd='dsage-ray mario eval --level levels/") == 5  # the table's copy buttons


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
    rows = [{"id": i, "level_file": f"levels/level_{i:04d}.txt", "seed": i, "episodes": 4, "success_a": 1.0,
             "success_b": 0.5 * i, "mean_path_length_a": 10.0, "mean_path_length_b": 12.5,
             "verdict": "worse" if i < 2 else "same"} for i in range(3)]
    comparison = {"agent_a": AGENT, "agent_b": REFERENCE, "levels": rows, "episodes_note": "4 episodes",
                  "columns": [{"key": "mean_path_length", "label": "mean_path_length", "mean": "mean path length"}],
                  "summary": {"levels": 3, "threshold": 0.1, "success_a": 1.0, "success_b": 0.5,
                              "mean_path_length_a": 10.0, "mean_path_length_b": 12.5, "solved_a": 3, "solved_b": 1,
                              "b_worse": 2, "b_better": 0}}
    path = write_compare_report(tmp_path / "page" / "compare.html", comparison, collection_dir=folder,
                                images={0: _png((0, 0, 0))})
    page = path.read_text()
    assert "class='sortable'" in page and page.count("<tr class='worse'>") == 2
    # The domain's compared column: its mean per agent, and per level A, B and the change.
    assert "<td class='l'>mean path length</td><td>10.00</td><td>12.50</td>" in page
    assert ">mean_<wbr>path_<wbr>length Δ</button></th>" in page and page.count("<td>+2.5</td>") == 3
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


def on_bin_edges(folder: Path) -> Path:
    """Gives the levels of a made collection integer measures on a 9 × 9 grid: 0..8 splits into regions at 2, 4
    and 6, so many levels lie on a region's edge, as Maze's integer measures do."""
    data = json.loads((folder / "collection.json").read_text())
    for entry in data["levels"]:
        a, b = divmod(entry["id"], 9)
        entry["measures"] = {"num_walls": float(a), "optimal_path_length": float(b)}
    (folder / "collection.json").write_text(json.dumps(data))
    return folder


def _region_rows(page: str) -> list[tuple[int, list[float], list[float]]]:
    """(levels, filter lows, filter highs) of each row of the region table."""
    table = page.split("<h2>Per-region statistics</h2>", 1)[1].split("</table>", 1)[0]
    rows = re.findall(r"<tr>(.*?)</tr>", table.split("<tbody>", 1)[1])
    out = []
    for row in rows:
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row)
        lo, hi = re.search(r"data-lo='([^']*)' data-hi='([^']*)'", row).groups()
        out.append((int(cells[0]), [float(v) for v in lo.split()], [float(v) for v in hi.split()]))
    return out


def _level_measures(page: str) -> list[list[float]]:
    body = page.split("id='levels'", 1)[1].split("<tbody>", 1)[1]
    return [[float(v) for v in m.split()] for m in re.findall(r"data-m='([^']*)'", body)]


def test_region_count_equals_the_levels_its_filter_selects(tmp_path):
    """What "show these" selects, by the page script's rule (lo <= value <= hi on every measure, both ends
    included), is exactly what the region table counts, levels on a region's edge included."""
    folder = on_bin_edges(make_collection(tmp_path / "c", levels=81))
    page = write_report(folder).read_text()
    measures = _level_measures(page)
    regions = _region_rows(page)
    assert len(measures) == 81 and len(regions) == 16 and sum(r[0] for r in regions) == 81
    for count, lows, highs in regions:
        selected = [m for m in measures if all(lo <= v <= hi for v, lo, hi in zip(m, lows, highs))]
        assert len(selected) == count, (lows, highs)


def test_tables_show_their_default_order_and_sort_from_the_keyboard(tmp_path):
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    levels_head = page.split("id='levels'", 1)[1].split("</thead>", 1)[0]
    # Worst first = ids ascending; the region table by mean objective, worst first.
    assert re.search(r"<th class='num' aria-sort='ascending'><button type='button' class='sort'>id</button>",
                     levels_head)
    regions = page.split("<h2>Per-region statistics</h2>", 1)[1].split("</table>", 1)[0]
    assert re.search(r"aria-sort='descending'><button type='button' class='sort'>mean failure rate</button>",
                     regions)
    assert levels_head.count("aria-sort") == 1 and regions.count("aria-sort") == 1
    # Every named header is a button (Tab reaches it, Enter and Space press it); the buttons' column has none.
    headers = re.findall(r"<th(?: [^>]*)?>(.*?)</th>", regions.split("</thead>", 1)[0])
    assert all(h.startswith("<button type='button' class='sort'>") for i, h in enumerate(headers) if i != 1)
    assert headers[1] == ""


def test_worst_level_is_a_link_to_its_row_and_sorts_as_a_number(tmp_path):
    folder = on_bin_edges(make_collection(tmp_path / "c", levels=81))
    page = write_report(folder).read_text()
    rows = set(re.findall(r"<tr id='level-(\d+)'", page))
    regions = page.split("<h2>Per-region statistics</h2>", 1)[1].split("</table>", 1)[0]
    head = re.findall(r"<th( [^>]*)?>(.*?)</th>", regions.split("</thead>", 1)[0])
    column = next(i for i, (_, text) in enumerate(head) if "worst level" in text)
    assert "class='num'" in head[column][0]
    worst = [re.findall(r"<td[^>]*>.*?</td>", row)[column] for row in re.findall(r"<tr>(.*?)</tr>", regions)[1:]]
    assert worst
    for cell in worst:
        key, target, text = re.fullmatch(r"<td data-sort='(\d+)'><a href='#level-(\d+)'>#(\d+)</a></td>", cell).groups()
        assert key == target == text and target in rows


def test_step_limit_is_explained_from_the_collection(tmp_path):
    folder = make_collection(tmp_path / "c", levels=5)
    data = json.loads((folder / "collection.json").read_text())
    data["max_steps"] = 336  # as the Maze records it for a 10×12 maze: 2·(10+2)·(12+2)
    (folder / "collection.json").write_text(json.dumps(data))
    page = write_report(folder).read_text()
    assert "<dt>step limit</dt><dd>336 steps per episode</dd>" in page
    note = ("mean steps per episode; a failed episode counts as the whole step limit, 336 steps, so 336 means "
            "the agent never reached the goal")
    assert f"<b>mean_path_length</b>: {note}.</p>" in page and "648" not in page
    # Where the numbers are: the header of the table of all levels, the region table, every card.
    assert re.search(rf"<th class='num' title='{note}'><button[^>]*>mean_<wbr>path_<wbr>length<", page)
    assert re.search(rf"title='{note}'><button[^>]*>mean path length<", page)
    assert page.count(f"<td class='l' title='{note}'>mean_path_length</td>") == 5
    # The limit is the collection's, not one the report knows.
    data["max_steps"] = 99
    (folder / "collection.json").write_text(json.dumps(data))
    assert "<dd>99 steps per episode</dd>" in write_report(folder).read_text()


def test_a_narrow_screen_scrolls_wide_tables_in_their_own_box(tmp_path):
    """The structure that keeps a 390 px page from scrolling sideways (test_report_browser.py measures it)."""
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    assert re.search(r"</p><div class='hscroll'><table class='sortable'><thead><tr><th class='num'", page)
    assert "</p><div class='scroll'><table class='sortable' id='levels'>" in page
    assert page.count("<p class='scrollhint' hidden>") == 2  # the script shows them where the box scrolls
    style = page.split("<style>", 1)[1].split("</style>", 1)[0]
    assert re.search(r"(^|\n)img \{ max-width: 100%;", style)
    # Grid columns never ask for more than the screen.
    assert not re.search(r"minmax\(\d+px", style) and style.count("minmax(min(") == 3


def _two_random_mazes():
    """An archive of two random valid mazes (objective 0.5) and the tiny audit config of a random agent."""
    from dsage_ray.audit.collection import audit_config
    from dsage_ray.domains import build_domain
    from dsage_ray.domains.maze.generator import random_valid_levels
    from dsage_ray.qd.archives import make_archive

    config = audit_config(agent="builtin:random", preset="tiny", seed=1, overrides={"maze.episodes": 2})
    domain = build_domain(config)
    levels = random_valid_levels(2, seed=1)
    archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges,
                           solution_dtype=domain.solution_dtype)
    archive.add(np.array([level.walls.ravel() for level in levels], dtype=np.int8), np.full(len(levels), 0.5),
                np.array([[level.num_walls, level.optimal_path_length] for level in levels], dtype=float))
    return archive, config


def test_reproduce_commands_run_from_any_directory(tmp_path, monkeypatch, capsys):
    """A collection written to a relative folder names its level files by absolute path."""
    import shlex

    from dsage_ray.audit.collection import build_collection
    from dsage_ray.cli import main

    archive, config = _two_random_mazes()
    (tmp_path / "project").mkdir()
    monkeypatch.chdir(tmp_path / "project")
    build_collection(archive, config=config, out_dir=Path("audits") / "collection")
    monkeypatch.chdir(tmp_path)  # elsewhere
    collection = load_collection(tmp_path / "project" / "audits" / "collection")
    assert len(collection["levels"]) == 2
    for lv in collection["levels"]:
        command = shlex.split(lv["reproduce"])
        layout = Path(command[command.index("--layout") + 1])
        assert layout.is_absolute() and layout == (tmp_path / "project" / "audits" / "collection" /
                                                   lv["level_file"]).resolve()
        capsys.readouterr()
        assert main(command[1:] + ["--json"]) == 0
        assert json.loads(capsys.readouterr().out)["success_rate"] == lv["success_rate"]


def test_the_report_command_renders_a_collection_again_from_its_folder_or_its_audit_folder(tmp_path, capsys):
    from dsage_ray.cli import main

    folder = make_collection(tmp_path / "audit" / "collection", levels=5)
    assert not (folder / "report.html").exists()
    assert main(["report", str(tmp_path / "audit")]) == 0
    assert capsys.readouterr().out == f"report: {folder / 'report.html'}\n"
    assert "<h1>" in (folder / "report.html").read_text()
    assert main(["report", str(tmp_path / "nowhere")]) == 2
    error = capsys.readouterr().err
    assert error.startswith("dsage-ray report: error: ") and "not a readable collection" in error


HOSTILE = "<script>window.hacked = 1</script>' onmouseover='window.hacked = 2' \""


def hostile_collection(folder: Path, outside_png: Path) -> Path:
    """A collection received from someone else: markup in every text field, file names that point elsewhere."""
    folder = make_collection(folder, levels=3, regression=True)
    data = json.loads((folder / "collection.json").read_text())
    measures = [f"{HOSTILE}a", f"{HOSTILE}b"]
    data.update(agent=HOSTILE, reference=HOSTILE, domain=HOSTILE, objective=HOSTILE, measures=measures,
                created=HOSTILE, notes=HOSTILE, search_dir=HOSTILE, episodes=HOSTILE, run_seed=HOSTILE,
                search_elites=HOSTILE, config={"preset": HOSTILE, "budget": HOSTILE})
    files = ["javascript:alert(1)", "http://example.com/x.txt", "/etc/passwd", "../../outside.txt"]
    for i, lv in enumerate(data["levels"]):
        lv["measures"] = dict(zip(measures, lv["measures"].values()))
        lv.update(level_file=files[i], layout_file=files[i], seed=HOSTILE, episodes=HOSTILE, search_objective=HOSTILE,
                  reproduce=f"dsage-ray maze eval --agent '{HOSTILE}' --layout {files[i]}", **{HOSTILE: 1.5})
        lv["image_file"] = [str(outside_png), "javascript:alert(1)", "../../outside.png"][i]
        lv["reference"].update(image_file="javascript:alert(2)", **{HOSTILE: 2.5})
    (folder / "collection.json").write_text(json.dumps(data))
    return folder


def test_a_hostile_collection_is_escaped_and_links_only_its_own_files(tmp_path):
    outside = tmp_path / "outside.png"
    outside.write_bytes(_png((1, 2, 3)))
    (tmp_path / "outside.txt").write_text("secret")
    folder = hostile_collection(tmp_path / "a" / "b", outside)
    page = write_report(folder).read_text()
    assert page.count("<script") == 1 and "window.hacked = 1</script>" not in page  # only the page's own script
    assert "onmouseover='" not in page and "onmouseover=\"" not in page  # no quote closes an attribute
    assert page.count("&lt;script&gt;window.hacked = 1&lt;/script&gt;&#x27; onmouseover=&#x27;") > 20
    links = _links(page)
    assert not [link for link in links if re.match(r"(?i)\s*(javascript|https?|file|data):", link)
                and not link.startswith("data:image/png;base64,")]
    assert not [link for link in links if link.startswith(("/", "..")) or "/.." in link]
    # The picture outside the collection is neither embedded nor linked: only the two heatmaps are embedded.
    assert page.count("src='data:image/png;base64,") == 2 and page.count("(no picture)") == 6
    assert base64.b64encode(outside.read_bytes()).decode() not in page
    # The refused names are shown as text.
    assert "<span title='not linked: not a file inside the collection folder'>javascript:alert(1)</span>" in page


def test_a_collection_whose_numbers_are_not_numbers_is_refused_by_name(tmp_path, capsys):
    from dsage_ray.cli import main

    folder = make_collection(tmp_path / "c", levels=3)
    good = (folder / "collection.json").read_text()
    breaks = {"level 1: success_rate": lambda data: data["levels"][1].update(success_rate=HOSTILE),
              "level 2: measure 'num_walls'": lambda data: data["levels"][2]["measures"].update(num_walls=HOSTILE),
              "level 0 has no integer id": lambda data: data["levels"][0].update(id=HOSTILE)}
    for message, spoil in breaks.items():
        data = json.loads(good)
        spoil(data)
        (folder / "collection.json").write_text(json.dumps(data))
        with pytest.raises(ValueError, match=re.escape(f"collection.json: {message}")):
            write_report(folder)
        assert main(["report", str(folder)]) == 2
        assert f"collection.json: {message}" in capsys.readouterr().err


def test_link_names_inside_the_collection_only():
    from dsage_ray.audit.report import collection_href

    assert collection_href("levels/level_0001.txt") == "levels/level_0001.txt"
    assert collection_href("levels/a b#c?.png") == "levels/a%20b%23c%3F.png"  # a file name, never a query
    for name in ("javascript:alert(1)", "JavaScript:x", "http://example.com/a", "//example.com/a", "/etc/passwd",
                 "../x", "levels/../../x", "C:/x", "levels\\x", "", None, 3):
        assert collection_href(name) is None, name


def test_shown_commands_run_in_the_collection_folder_wherever_it_is(tmp_path, monkeypatch, capsys):
    """The page's commands name the level file relative to the collection folder and say to run them there:
    moved elsewhere, the folder's first command prints the recorded numbers again."""
    import html
    import shlex
    import shutil

    from dsage_ray.audit.collection import build_collection
    from dsage_ray.cli import main

    archive, config = _two_random_mazes()
    built = build_collection(archive, config=config, out_dir=tmp_path / "here" / "collection")
    moved = Path(shutil.move(built, tmp_path / "there" / "received"))
    page = write_report(moved).read_text()
    assert "Run a level's command in the collection folder" in page
    codes = re.findall(r"<code class='cmd'>(.*?)</code>", page)
    shown = [html.unescape(re.sub(r"</?span>", "", code)) for code in codes]
    assert len(shown) == 2 and not [command for command in shown if str(tmp_path) in command]
    first = load_collection(moved)["levels"][0]
    assert f"--layout {first['level_file']} " in shown[0]
    monkeypatch.chdir(moved)
    capsys.readouterr()
    assert main(shlex.split(shown[0])[1:] + ["--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert (again["success_rate"], again["mean_path_length"]) == (first["success_rate"], first["mean_path_length"])


def test_one_failure_number_per_level(tmp_path):
    """The failure rate once: one column in the table, once per card (its headline), no success-rate column;
    the picture's title (written by the collection) names the level, not its numbers."""
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    levels_head = page.split("id='levels'", 1)[1].split("</thead>", 1)[0]
    assert levels_head.count(">failure rate</button>") == 1 and "success" not in levels_head
    assert "failure_<wbr>rate" not in levels_head
    for card in page.split("<h2>Per-region")[0].split("<div class='card'>")[1:]:
        assert card.count("failure rate") == 1 and "success" not in card
        assert re.search(r"<h3>#\d+: failure rate \d\.\d{3}</h3>", card)
    # An objective that is another number than the failure rate keeps its column, beside the failure rate.
    data = json.loads((folder / "collection.json").read_text())
    data["objective"] = "regret"
    for lv in data["levels"]:
        lv["objective"] = lv["id"] / 20
    (folder / "collection.json").write_text(json.dumps(data))
    page = write_report(folder).read_text()
    levels_head = page.split("id='levels'", 1)[1].split("</thead>", 1)[0]
    assert ">regret</button>" in levels_head and levels_head.count(">failure rate</button>") == 1


def test_the_collection_draws_pictures_that_name_their_level_only(tmp_path):
    from dsage_ray.audit.collection import audit_config, build_collection
    from dsage_ray.domains import build_domain
    from dsage_ray.domains.maze.generator import random_valid_levels
    from dsage_ray.qd.archives import make_archive

    from .test_pictures import drawn_figures

    config = audit_config(agent="builtin:random", preset="tiny", seed=1, overrides={"maze.episodes": 2})
    domain = build_domain(config)
    level = random_valid_levels(1, seed=2)[0]
    archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges,
                           solution_dtype=domain.solution_dtype)
    archive.add(np.array([level.walls.ravel()], dtype=np.int8), np.full(1, 0.5),
                np.array([[level.num_walls, level.optimal_path_length]], dtype=float))
    _, figures = drawn_figures(lambda: build_collection(archive, config=config, out_dir=tmp_path / "c"))
    picture = [[t.text for t in texts] for texts, _ in figures if "level #0" in [t.text for t in texts]]
    assert len(picture) == 1 and not [t for t in picture[0] if "success" in t or "failure" in t]


def test_the_glossary_explains_every_term_and_the_ties(tmp_path):
    folder = make_collection(tmp_path / "c", levels=15)
    page = write_report(folder).read_text()
    glossary = page.split("<dl class='glossary' id='terms'>", 1)[1].split("</dl>", 1)[0]
    terms = re.findall(r"<dt>(.*?)</dt>", glossary)
    assert terms == ["failure rate", "search objective", "measures", "archive cell", "elite", "coverage", "CVaR",
                     "ties"]
    for term in ("archive cell", "CVaR", "coverage", "search objective"):
        assert term in page.replace(glossary, ""), term  # each is used outside the glossary too
    assert "QD-score" not in page
    assert "levels with the same failure rate are listed with the higher search objective first" in glossary
    regression = write_report(make_collection(tmp_path / "r", levels=9, regression=True)).read_text()
    assert "<dt>regression</dt>" in regression
    assert "levels with the same regression are listed with the lower success rate first" in regression


def test_region_ranges_are_printed_as_the_filter_takes_them(tmp_path):
    """A region's button fills in the range its row prints (its levels' lowest and highest values), rounded
    outward only as far as no other level is taken in."""
    from dsage_ray.audit.report import printed_range

    folder = on_bin_edges(make_collection(tmp_path / "c", levels=81))
    page = write_report(folder).read_text()
    table = page.split("<h2>Per-region statistics</h2>", 1)[1].split("</table>", 1)[0]
    for row in re.findall(r"<tr>(.*?)</tr>", table.split("<tbody>", 1)[1]):
        lo, hi = re.search(r"data-lo='([^']*)' data-hi='([^']*)'", row).groups()
        ranges = re.findall(r"<td data-sort='[^']*'>([^<]*)</td>", row)[-2:]
        assert [r.split(" – ") for r in ranges] == [[a] if a == b else [a, b] for a, b in zip(lo.split(), hi.split())]
    assert printed_range(1.23456, 2.5, [1.23456, 2.5, 2.6], 3) == ("1.234", "2.500")
    assert printed_range(1.23456, 2.5, [1.2342, 1.23456, 2.5], 3) == ("1.2345", "2.5000")


def test_one_episode_is_one_episode_on_the_page():
    from dsage_ray.audit.report.collection_page import episodes_phrase

    assert (episodes_phrase(1), episodes_phrase(5), episodes_phrase("<2>")) == ("1 episode", "5 episodes",
                                                                              "&lt;2&gt; episodes")
