"""``benchmarks/metrics.py``: the mean ± standard error the result tables print."""

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from metrics import format_mean_se, mean_se  # noqa: E402


def test_mean_se():
    assert mean_se([1.0, 3.0]) == (2.0, 1.0)
    mean, se = mean_se([4.0])
    assert mean == 4.0 and math.isnan(se)
    assert format_mean_se(4.0, se, ".1f") == "4.0"
    assert format_mean_se(*mean_se([1_590.0, 1_604.0]), ",.1f") == "1,597.0 ± 7.0"
