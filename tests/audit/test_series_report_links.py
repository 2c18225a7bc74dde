"""series.html links only files inside the series folder (series.json may come from someone else)."""

from __future__ import annotations

import re

from dsage_ray.audit.series_report import write_series_report

from .test_report import HOSTILE
from .test_series import synthetic_series


def test_series_page_links_its_own_files_only(tmp_path):
    data = synthetic_series(checkpoints=3)
    files = ["javascript:alert(1)", "/etc/passwd", "checkpoints/000-a/collection/levels/level_0000.txt"]
    for level, file in zip(data["suite"], files):
        level.update(level_file=file)
    data["suite"][0]["id"] = HOSTILE
    for record, folder in zip(data["records"], ("/elsewhere", "javascript:x", "checkpoints/000-a")):
        record["audit_dir"] = folder
    (tmp_path / "checkpoints" / "000-a" / "collection").mkdir(parents=True)
    (tmp_path / "checkpoints" / "000-a" / "collection" / "report.html").write_text("<p>report</p>")
    page = write_series_report(tmp_path, data).read_text()
    hrefs = re.findall(r"href='([^']*)'", page)
    assert sorted(hrefs) == ["checkpoints/000-a/collection/levels/level_0000.txt",
                             "checkpoints/000-a/collection/report.html"], hrefs
    assert page.count("<script") == 1 and "&lt;script&gt;" in page
