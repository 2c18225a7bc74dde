"""``dsage_ray.core.metrics``: the mean ± standard error the result tables print."""

import math

from dsage_ray.core.metrics import format_mean_se, mean_se


def test_mean_se():
    assert mean_se([1.0, 3.0]) == (2.0, 1.0)
    mean, se = mean_se([4.0])
    assert mean == 4.0 and math.isnan(se)
    assert format_mean_se(4.0, se, ".1f") == "4.0"
    assert format_mean_se(*mean_se([1_590.0, 1_604.0]), ",.1f") == "1,597.0 ± 7.0"
