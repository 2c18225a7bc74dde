"""The domain contract as capabilities: a required Domain protocol, optional ones found by ``isinstance``, and the
registration's declarations that let a config or the audit's CLI be checked without importing a domain."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsage_ray import types
from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.domains import DEFAULT_DOMAIN, get_domain
from dsage_ray.surrogate.surrogate import domain_level_values, domain_prior

OPTIONAL = (types.RenderableDomain, types.PreflightDomain, types.BoundedDomain, types.ScreenableDomain,
            types.CostModelDomain, types.PriorDomain, types.LevelValuesDomain, types.WorkCountingDomain,
            types.AuditableDomain, types.NominalDomain)


class Minimal:
    """The required members only: a 2-cell bitmap whose objective is its wall count."""

    name = "minimal"
    solution_dim = 2
    measure_names = ("walls",)
    measure_ranges = ((0.0, 2.0),)
    archive_dims = (3,)
    occupancy_shape = (1, 2)
    encoding_channels = 1
    encoding_pad_channel = 0
    solution_dtype = np.int8

    def random_solutions(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return rng.integers(0, 2, size=(n, 2)).astype(np.int8)

    random_valid_solutions = random_solutions

    def encode(self, solutions: np.ndarray) -> np.ndarray:
        return np.asarray(solutions, dtype=np.float32).reshape(-1, 1, 1, 2)

    def evaluate(self, solution: np.ndarray, seed: int) -> types.EvaluationResult:
        walls = float(np.sum(solution))
        return types.EvaluationResult(objective=walls, measures=np.array([walls]), occupancy=np.zeros((1, 2)))


@dataclasses.dataclass
class Bounded:
    solution_bounds: tuple[float, float] | None


def test_a_domain_with_the_required_members_only_has_no_optional_capability():
    domain = Minimal()
    assert isinstance(domain, types.Domain)
    assert [protocol.__name__ for protocol in OPTIONAL if isinstance(domain, protocol)] == []
    assert types.solution_bounds(domain) is None
    with pytest.raises(ValueError, match="surrogate.prior_measure 'x': the .* domain has no prior for it"):
        domain_prior(domain, "x")
    with pytest.raises(ValueError, match=r"surrogate.exact_level_values: .* \(it has no level_values\)"):
        domain_level_values(domain)


def test_a_declared_capability_is_read_through_its_protocol():
    assert types.solution_bounds(Bounded((-2.0, 3.0))) == (-2.0, 3.0)
    # Declaring the member with None is declaring no box, as before.
    assert types.solution_bounds(Bounded(None)) is None


@pytest.mark.parametrize("name", ["maze", "mario", "gym"])
def test_each_shipped_registration_says_whether_its_domain_screens(name):
    spec = get_domain(name)
    assert spec.screenable == issubclass(spec.domain_class(), types.ScreenableDomain)


def test_the_screening_keys_apply_only_to_a_screenable_domain():
    assert RunConfig.build(domain="maze", preset="tiny", **{"selection.screen_episodes": 1}).selection.screen_episodes
    with pytest.raises(ConfigError) as error:
        RunConfig.build(domain="gym", preset="tiny", **{"selection.screen_episodes": 1})
    message = str(error.value)
    assert message.startswith("selection.screen_episodes: ") and "domain 'gym' has none" in message
    assert "\n" not in message


def test_the_default_domain_is_one_name_used_everywhere():
    import inspect

    from dsage_ray.audit.run import default_audit_folder, run_audit
    from dsage_ray.cli import build_parser

    assert RunConfig().domain == DEFAULT_DOMAIN
    assert inspect.signature(run_audit).parameters["domain"].default == DEFAULT_DOMAIN
    assert inspect.signature(default_audit_folder).parameters["domain"].default == DEFAULT_DOMAIN
    assert build_parser().parse_args(["audit"]).domain == DEFAULT_DOMAIN
    assert get_domain(DEFAULT_DOMAIN).name == DEFAULT_DOMAIN
