"""Self-contained HTML pages for a collection (``report.html``) and an agent comparison.

One module per part: :mod:`~dsage_ray.audit.report.blocks` (escaping, links, pictures, tables, the page, whose
CSS and script are the package data ``assets/report.css`` and ``assets/report.js``),
:mod:`~dsage_ray.audit.report.statistics` (the numbers the page computes and checks),
:mod:`~dsage_ray.audit.report.heatmaps` (the archive pictures), and the two pages,
:mod:`~dsage_ray.audit.report.collection_page` and :mod:`~dsage_ray.audit.report.compare_page`.
"""

from dsage_ray.audit.report.blocks import collection_href, portable_command
from dsage_ray.audit.report.collection_page import WORST_SHOWN, write_report
from dsage_ray.audit.report.compare_page import write_compare_report
from dsage_ray.audit.report.heatmaps import PICTURE_MIN_WIDTH, heatmap_pngs
from dsage_ray.audit.report.statistics import (REGIONS_PER_MEASURE, check_numbers, printed_range, region_statistics,
                                               report_columns)

__all__ = ["PICTURE_MIN_WIDTH", "REGIONS_PER_MEASURE", "WORST_SHOWN", "check_numbers", "collection_href",
           "heatmap_pngs", "portable_command", "printed_range", "region_statistics", "report_columns",
           "write_compare_report", "write_report"]
