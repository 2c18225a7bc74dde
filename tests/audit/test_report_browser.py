"""report.html in a real browser: headless Chromium from the distribution's packages, driven by Selenium.

Sorts and filters the level table the way a person would and checks that the page logs no console error.
Skips where Chromium, its driver or the ``selenium`` package (the ``dev`` extra) is missing.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pytest

from .test_report import make_collection

@contextlib.contextmanager
def viewport(driver, width: int, height: int):
    """The page as a screen ``width`` x ``height`` CSS pixels shows it (a phone's below 500 px wide)."""
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": width < 500})
    try:
        yield
    finally:
        driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})


def _visible_ids(driver) -> list[int]:
    return [int(v) for v in driver.execute_script(
        "return Array.from(document.querySelectorAll('#levels tbody tr'))"
        ".filter(r => !r.hidden).map(r => r.cells[0].textContent);")]


def _header(driver, text: str):
    from selenium.webdriver.common.by import By

    return next(th for th in driver.find_elements(By.CSS_SELECTOR, "#levels thead th") if th.text.startswith(text))


def test_report_sorts_filters_and_logs_no_error(browser, tmp_path):
    from selenium.webdriver.common.by import By

    from dsage_ray.audit.report import write_report

    folder = make_collection(tmp_path / "c", levels=15)
    browser.get(write_report(folder).resolve().as_uri())
    assert _visible_ids(browser) == list(range(15))
    assert browser.find_element(By.ID, "shown").text == "15 of 15 levels shown"

    # mean_path_length = 50.5 + id: ascending, then descending on a second click.
    header = _header(browser, "mean_path_length")
    header.click()
    assert _visible_ids(browser) == list(range(15))
    assert header.get_attribute("aria-sort") == "ascending"
    header.click()
    assert _visible_ids(browser) == list(range(14, -1, -1))
    # Numbers sort as numbers: 10 after 9, not after 1.
    _header(browser, "id").click()
    assert _visible_ids(browser) == list(range(15))
    # One failure column (the objective is the failure rate): its first click puts the worst first.
    assert not [th.text for th in browser.find_elements(By.CSS_SELECTOR, "#levels thead th")
                if "success" in th.text or "failure_rate" in th.text]
    failure = _header(browser, "failure rate")
    failure.click()
    assert failure.get_attribute("aria-sort") == "descending"
    failures = [1 - [0, 0.25, 0.5, 0.75, 1][i % 5] for i in _visible_ids(browser)]
    assert failures == sorted(failures, reverse=True)
    _header(browser, "id").click()
    # The text filter reads what the rows show, not their reproduce commands (every one names "maze").
    browser.find_element(By.ID, "query").send_keys("maze")
    assert _visible_ids(browser) == []
    browser.find_element(By.ID, "reset").click()

    # Success rates cycle 0, 0.25, 0.5, 0.75, 1: never solved = ids 0, 5, 10.
    browser.find_element(By.ID, "never").click()
    assert _visible_ids(browser) == [0, 5, 10]
    assert browser.find_element(By.ID, "shown").text == "3 of 15 levels shown"
    # Text filter on top: the level file name.
    browser.find_element(By.ID, "query").send_keys("level_0005.")
    assert _visible_ids(browser) == [5]
    browser.find_element(By.ID, "reset").click()
    assert _visible_ids(browser) == list(range(15))

    # Range filter on the first measure (num_walls = 100 + 3 id): 106 to 112 keeps ids 2, 3, 4.
    browser.find_element(By.CSS_SELECTOR, "input.lo[data-j='0']").send_keys("106")
    browser.find_element(By.CSS_SELECTOR, "input.hi[data-j='0']").send_keys("112")
    assert _visible_ids(browser) == [2, 3, 4]
    browser.find_element(By.ID, "reset").click()
    # A region button fills the range inputs with its region: every level it shows lies in that region.
    button = browser.find_element(By.CSS_SELECTOR, "button.region")
    lows = [float(v) for v in button.get_attribute("data-lo").split()]
    highs = [float(v) for v in button.get_attribute("data-hi").split()]
    button.click()
    shown = _visible_ids(browser)
    assert 0 < len(shown) < 15
    assert all(lows[0] <= 100 + 3 * i <= highs[0] and lows[1] <= 20 + i % 7 <= highs[1] for i in shown)

    # A row's copy button copies that row's reproduce command (the clipboard is stubbed to read it back).
    browser.execute_script("navigator.clipboard.writeText = function (text) { window.copied = text; "
                           "return Promise.resolve(); };")
    browser.find_element(By.ID, "reset").click()
    row = browser.find_elements(By.CSS_SELECTOR, "#levels tbody tr")[3]
    button = row.find_element(By.CSS_SELECTOR, "button.copy")
    button.click()
    assert browser.execute_script("return window.copied;") == button.get_attribute("data-cmd")
    assert "--layout levels/level_0003.txt --episodes 4 --seed 1003" in browser.execute_script("return window.copied;")
    # A card's copy button copies the command printed beside it.
    card = browser.find_element(By.CSS_SELECTOR, ".card")
    card.find_element(By.CSS_SELECTOR, "button.copy").click()
    assert browser.execute_script("return window.copied;") == card.find_element(By.CSS_SELECTOR, "code.cmd").text

    errors = [entry for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]
    assert errors == [], errors


def test_regression_report_filters_regressed_levels(browser, tmp_path):
    from selenium.webdriver.common.by import By

    from dsage_ray.audit.report import write_report

    folder = make_collection(tmp_path / "r", levels=9, regression=True)
    browser.get(write_report(folder).resolve().as_uri())
    browser.find_element(By.ID, "regressed").click()
    # Regression 0.5 where id % 3 != 0 and the success rate leaves room, else 0.
    expected = {i for i in range(9) if i % 3 and (i % 5) / 4 < 1}
    assert set(_visible_ids(browser)) == expected
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []


def test_every_region_shows_as_many_levels_as_it_counts(browser, tmp_path):
    from selenium.webdriver.common.by import By

    from dsage_ray.audit.report import write_report

    from .test_report import on_bin_edges

    folder = on_bin_edges(make_collection(tmp_path / "c", levels=81))
    browser.get(write_report(folder).resolve().as_uri())
    buttons = browser.find_elements(By.CSS_SELECTOR, "button.region")
    assert len(buttons) == 16
    for button in buttons:
        count = int(button.find_element(By.XPATH, "./ancestor::tr/td[1]").text)
        button.click()
        assert len(_visible_ids(browser)) == count, button.get_attribute("data-lo")
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []


def test_headers_sort_from_the_keyboard_and_worst_level_opens_its_row(browser, tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    from dsage_ray.audit.report import write_report

    folder = make_collection(tmp_path / "c", levels=15)
    browser.get(write_report(folder).resolve().as_uri())
    assert _header(browser, "id").get_attribute("aria-sort") == "ascending"  # the order it opens in
    # Tab reaches the headers (the first one right after the filters' reset button); Enter sorts, Space sorts back.
    browser.find_element(By.ID, "reset").send_keys(Keys.TAB)
    assert browser.switch_to.active_element == _header(browser, "id").find_element(By.CSS_SELECTOR, "button")
    button = _header(browser, "mean_path_length").find_element(By.CSS_SELECTOR, "button")
    browser.execute_script("arguments[0].focus();", button)
    button.send_keys(Keys.ENTER)
    assert _header(browser, "mean_path_length").get_attribute("aria-sort") == "ascending"
    assert _header(browser, "id").get_attribute("aria-sort") is None
    button.send_keys(Keys.SPACE)
    assert _visible_ids(browser) == list(range(14, -1, -1))

    # "worst level" sorts as a number (#10 after #9) and its link opens the row, even when a filter hid it.
    regions = browser.find_element(By.XPATH, "//h2[text()='Per-region statistics']/following::table[1]")
    worst = next(th for th in regions.find_elements(By.CSS_SELECTOR, "th") if th.text.startswith("worst level"))
    worst.click()
    column = worst.get_property("cellIndex")
    ids = [int(row.find_elements(By.CSS_SELECTOR, "td")[column].text.lstrip("#"))
           for row in regions.find_elements(By.CSS_SELECTOR, "tbody tr")]
    assert min(ids) < 10 <= max(ids) and ids == sorted(ids)
    link = regions.find_elements(By.CSS_SELECTOR, "tbody tr")[-1].find_element(By.TAG_NAME, "a")
    target = link.get_attribute("href").split("#")[1]
    browser.find_element(By.ID, "query").send_keys("no such level")
    assert _visible_ids(browser) == []
    link.click()
    row = browser.find_element(By.ID, target)
    assert row.is_displayed() and browser.execute_script("return location.hash") == f"#{target}"


def test_page_fits_a_phone(browser, tmp_path):
    """At 390 px wide nothing scrolls the page sideways; the wide tables scroll inside their own box."""
    from dsage_ray.audit.report import write_report

    folder = make_collection(tmp_path / "c", levels=15)
    data = json.loads((folder / "collection.json").read_text())
    data["search_dir"] = "/a/rather/long/path/" + "deep_folder_name_" * 6 + "search"
    (folder / "collection.json").write_text(json.dumps(data))
    page = write_report(folder)
    # The report's heatmaps are real 700 px figures (matplotlib); the level pictures in the cards are tiny here.
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": 390, "height": 844, "deviceScaleFactor": 1, "mobile": True})
    try:
        browser.get(page.resolve().as_uri())
        assert browser.execute_script("return document.documentElement.scrollWidth") <= 390
        assert browser.execute_script("return window.innerWidth") == 390
        # The tables are wider than the screen: they scroll inside their box, which holds them.
        for box in ("div.hscroll", "div.scroll"):
            inner, outer = browser.execute_script(
                f"var b = document.querySelector('{box}'); return [b.scrollWidth, b.clientWidth];")
            assert inner > outer and outer <= 390, box
    finally:
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})


@pytest.mark.parametrize("width,height", [(1400, 1000), (390, 844)])
def test_picture_labels_are_legible_on_the_page(browser, tmp_path, width, height):
    """The smallest text of the level pictures and heatmaps, at the size the page shows them, is at least
    MIN_TEXT_PX: its size in the PNG (recorded as matplotlib draws it) times the shown width over the PNG's."""
    from dsage_ray.audit.report import PICTURE_MIN_WIDTH, write_report

    from .test_pictures import MIN_TEXT_PX, heatmap_pictures, maze_picture

    folder = make_collection(tmp_path / "c", levels=15)
    level = maze_picture()
    for png in (folder / "levels").glob("*.png"):
        png.write_bytes(level.png)
    heatmaps = dict(zip(("heatmap, zoomed", "heatmap, full range"), heatmap_pictures(tmp_path / "h")))
    page = write_report(folder)
    with viewport(browser, width, height):
        browser.get(page.resolve().as_uri())
        shown = browser.execute_script(
            "return Array.from(document.querySelectorAll('.card img, .figs img'), "
            "i => [i.alt, i.getBoundingClientRect().width, i.naturalWidth]);")
    assert len(shown) == 2 + 12
    for alt, shown_width, natural_width in shown:
        picture = heatmaps.get(alt, level)
        assert natural_width == picture.width, alt
        assert shown_width >= PICTURE_MIN_WIDTH, alt
        assert picture.smallest_text_on_page(shown_width) >= MIN_TEXT_PX, (alt, shown_width)


def test_tables_show_their_counts_on_a_phone_and_say_when_they_scroll(browser, tmp_path):
    """At 390 px: each table's first columns (a region's level count and its button; a level's id and failure
    rate) lie inside the table's box, and a line above each table says that it scrolls sideways. At 1,400 px the
    levels table fits, so its line is hidden."""
    from selenium.webdriver.common.by import By

    from dsage_ray.audit.report import write_report

    page = write_report(make_collection(tmp_path / "c", levels=15))
    with viewport(browser, 390, 844):
        browser.get(page.resolve().as_uri())
        hints = browser.find_elements(By.CSS_SELECTOR, ".scrollhint")
        assert len(hints) == 2 and all(hint.is_displayed() for hint in hints)
        assert "scroll it sideways" in hints[0].text
        for box, cells in (("div.hscroll", ("levels", "")), ("div.scroll", ("id", "failure rate"))):
            inside = browser.execute_script(
                "var box = document.querySelector(arguments[0]), edge = box.getBoundingClientRect().right;"
                "var row = box.querySelector('tbody tr');"
                "return [box.querySelector('thead tr').cells[0].textContent, box.querySelector('thead tr').cells[1]"
                ".textContent, row.cells[0].getBoundingClientRect().right <= edge,"
                " row.cells[1].getBoundingClientRect().right <= edge];", box)
            assert inside == [*cells, True, True], box
    browser.get(page.resolve().as_uri())  # 1,400 px
    assert [hint.is_displayed() for hint in browser.find_elements(By.CSS_SELECTOR, ".scrollhint")] == [False, False]
    assert browser.execute_script("var b = document.querySelector('div.scroll'); return b.scrollWidth <= b.clientWidth")


def test_a_region_clears_the_other_filters_and_fills_in_its_printed_range(browser, tmp_path):
    from selenium.webdriver.common.by import By

    from dsage_ray.audit.report import write_report

    from .test_report import on_bin_edges

    browser.get(write_report(on_bin_edges(make_collection(tmp_path / "c", levels=81))).resolve().as_uri())
    browser.find_element(By.ID, "query").send_keys("level_")
    browser.find_element(By.ID, "never").click()
    row = browser.find_elements(By.CSS_SELECTOR, ".hscroll tbody tr")[3]
    row.find_element(By.CSS_SELECTOR, "button.region").click()
    assert browser.find_element(By.ID, "query").get_attribute("value") == ""
    assert not browser.find_element(By.ID, "never").is_selected()
    printed = [cell.text for cell in row.find_elements(By.CSS_SELECTOR, "td")[4:6]]
    filled = [[box.get_attribute("value") for box in browser.find_elements(By.CSS_SELECTOR, f"input.{end}")]
              for end in ("lo", "hi")]
    assert [text.split(" – ") for text in printed] == [[lo] if lo == hi else [lo, hi] for lo, hi in zip(*filled)]
    assert len(_visible_ids(browser)) == int(row.find_element(By.CSS_SELECTOR, "td").text)


def test_a_hostile_collection_runs_no_script_and_links_nowhere_else(browser, tmp_path):
    from dsage_ray.audit.report import write_report

    from .test_report import _png, hostile_collection

    outside = tmp_path / "outside.png"
    outside.write_bytes(_png((1, 2, 3)))
    page = write_report(hostile_collection(tmp_path / "a" / "b", outside))
    browser.get(page.resolve().as_uri())
    for element in browser.find_elements("css selector", "td, th, dd, code, h1, h3"):
        browser.execute_script("arguments[0].dispatchEvent(new MouseEvent('mouseover', {bubbles: true}));", element)
    assert browser.execute_script("return [document.scripts.length, window.hacked === undefined];") == [1, True]
    folder = (tmp_path / "a" / "b").resolve().as_uri()
    links = browser.execute_script("return Array.from(document.links, a => a.href);")
    assert links and all(link.startswith(folder + "/") for link in links), links
    assert [e for e in browser.get_log("browser") if e["level"] == "SEVERE"] == []
