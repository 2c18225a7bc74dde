"""The screen a run builds from its config (``dsage_ray.core.screening.domain_screen``)."""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core.screening import domain_screen
from dsage_ray.core.seeds import RunSeeds
from tests.fakes import ScreeningBitmapDomain


class PrecisionScreeningDomain(ScreeningBitmapDomain):
    """Records the precision each screen was asked for."""

    def __init__(self, **options) -> None:
        super().__init__(**options)
        self.precisions: list[str] = []

    def screen(self, solutions, *, episodes, seed, precision="fp32"):
        self.precisions.append(precision)
        return super().screen(solutions, episodes=episodes, seed=seed)


def _config(precision: str) -> RunConfig:
    return RunConfig.build({"domain": "maze", "preset": "tiny", "variant": "dsage",
                            "selection.screen_episodes": 1, "experimental.screen_precision": precision})


@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_the_screen_passes_its_precision_to_a_domain_that_takes_one(precision):
    domain = PrecisionScreeningDomain()
    screen = domain_screen(_config(precision), domain, RunSeeds(seed=0))
    objective, measures = screen(domain.random_solutions(3, np.random.default_rng(0)))
    assert domain.precisions == [precision] and objective.shape == (3,) and measures.shape[0] == 3


def test_auto_resolves_by_the_cpu(monkeypatch):
    import dsage_ray.surrogate.surrogate as surrogate

    for native, expected in ((True, "bf16"), (False, "fp32")):
        monkeypatch.setattr(surrogate, "native_cpu_bf16", lambda native=native: native)
        domain = PrecisionScreeningDomain()
        domain_screen(_config("auto"), domain, RunSeeds(seed=0))(domain.random_solutions(2, np.random.default_rng(0)))
        assert domain.precisions == [expected]

