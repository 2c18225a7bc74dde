"""The domain registry: entry-point discovery, registration errors, unknown names."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import subprocess
import sys

import pytest

from dsage_ray.config import RunConfig, presets, variants
from dsage_ray.domains import registry
from dsage_ray.domains.registry import DomainSpec, domain_names, get_domain, register_domain, unregister_domain
from dsage_ray.errors import InputError


@dataclasses.dataclass
class ToyConfig:
    size: int = 4
    measures: tuple[str, ...] = ("a", "b")
    archive_dims: tuple[int, ...] = (4, 4)
    measure_ranges: tuple[tuple[float, float], ...] = ((0.0, 1.0), (0.0, 1.0))

    def validate(self, need) -> None:
        need(self.size >= 2, "size", "must be at least 2")


def toy_spec(name: str = "toy", **changes) -> DomainSpec:
    values = dict(name=name, config=ToyConfig, domain="tests.fakes:BitmapDomain",
                  presets={"paper": {}, "tiny": {"budget": 10, "toy.size": 3}},
                  variants={"dr": {"surrogate.kind": "none", "qd.emitter": "random"}}, comparison=("dsage", "dr"))
    values.update(changes)
    return DomainSpec(**values)


@pytest.fixture
def toy():
    spec = register_domain(toy_spec())
    yield spec
    unregister_domain("toy")


def test_maze_and_mario_come_from_dsage_rays_own_entry_points():
    points = {p.name: p.value for p in importlib.metadata.entry_points(group=registry.ENTRY_POINT_GROUP)}
    assert points["maze"] == "dsage_ray.domains.maze.plugin:DOMAIN"
    assert points["mario"] == "dsage_ray.domains.mario.plugin:DOMAIN"
    assert points["gym"] == "dsage_ray.domains.gym.plugin:DOMAIN"
    assert domain_names()[:3] == ["gym", "mario", "maze"]
    maze = get_domain("maze")
    assert maze.audit.episodes_key == "maze.episodes" and maze.domain_class().__name__ == "MazeDomain"
    assert get_domain("mario").audit.default_agent == "astar" and get_domain("mario").actor_env is not None


def test_importing_the_package_and_building_a_mario_config_imports_no_simulator():
    code = ("import sys, dsage_ray.cli, dsage_ray.config as c; c.RunConfig.build(domain='mario', preset='tiny'); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'minigrid', 'jpype', 'torch', 'ray'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_registered_domain_gets_a_config_section_presets_and_variants(toy):
    config = RunConfig.build({"domain": "toy", "preset": "tiny", "variant": "dr"})
    assert (config.toy.size, config.budget, config.qd.emitter) == (3, 10, "random")
    assert list(config.sections) == ["toy"] and config.to_flat()["toy.size"] == 3
    assert RunConfig.build(config.to_flat()) == config
    assert set(variants("toy")) >= {"dsage", "dsage_basic", "dr"} and set(presets("toy")) == {"paper", "tiny"}
    with pytest.raises(InputError, match=r"toy.size: must be at least 2 \(got 1\)"):
        RunConfig.build({"domain": "toy", "toy.size": 1})
    with pytest.raises(InputError, match="toy.sise: unknown config key .*did you mean toy.size"):
        RunConfig.build({"domain": "toy", "toy.sise": 1})
    assert "toy" in domain_names()


def test_registering_a_second_spec_under_a_taken_name_is_an_error(toy):
    assert register_domain(toy) is toy  # the same spec again: nothing to do
    with pytest.raises(InputError, match="domain 'toy' is already registered"):
        register_domain(toy_spec())
    get_domain("maze")
    with pytest.raises(InputError, match="domain 'maze' is already registered"):
        register_domain(toy_spec("maze"))


def test_an_unknown_domain_lists_the_known_ones_with_a_guess():
    with pytest.raises(InputError) as error:
        get_domain("mazr")
    assert "unknown domain 'mazr' (known: gym, mario, maze" in str(error.value)
    assert str(error.value).endswith("; did you mean 'maze'?")


@pytest.mark.parametrize("changes, message", [
    ({"name": "two words"}, "must be a Python identifier"),
    ({"config": dict}, "config must be a dataclass"),
    ({"presets": {"tiny": {}}}, "presets need a 'paper' entry"),
    ({"domain": "tests.fakes.BitmapDomain"}, "domain must read 'module:Class'"),
])
def test_a_malformed_spec_is_refused_when_made(changes, message):
    with pytest.raises(InputError, match=message):
        toy_spec(**changes)


def test_a_section_without_measures_is_refused():
    @dataclasses.dataclass
    class Bare:
        size: int = 1

    with pytest.raises(InputError, match=r"lacks \['archive_dims', 'measure_ranges', 'measures'\]"):
        toy_spec(config=Bare)


def fake_entry_points(monkeypatch, *points: importlib.metadata.EntryPoint) -> None:
    real = importlib.metadata.entry_points

    def entry_points(**kwargs):
        if kwargs.get("group") == registry.ENTRY_POINT_GROUP:
            return importlib.metadata.EntryPoints([*real(**kwargs), *points])
        return real(**kwargs)

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    registry._scan(refresh=True)


@pytest.fixture
def restore_scan(monkeypatch):
    yield
    # Fixtures are torn down in reverse order, so the fake entry points would still be patched in: undo them first,
    # or the rescan caches them for every later test of this process.
    monkeypatch.undo()
    registry._scan(refresh=True)


def test_two_packages_claiming_one_name_fail_when_it_is_used(monkeypatch, restore_scan):
    group = registry.ENTRY_POINT_GROUP
    fake_entry_points(monkeypatch, importlib.metadata.EntryPoint("clash", "pkg_a.plugin:DOMAIN", group),
                      importlib.metadata.EntryPoint("clash", "pkg_b.plugin:DOMAIN", group))
    assert "clash" in domain_names() and get_domain("maze").name == "maze"  # the others still work
    with pytest.raises(InputError, match="domain 'clash' is registered twice: 'pkg_a.plugin:DOMAIN' and 'pkg_b"):
        get_domain("clash")


def test_an_entry_point_must_load_to_a_spec_of_its_name(monkeypatch, restore_scan):
    group = registry.ENTRY_POINT_GROUP
    fake_entry_points(monkeypatch, importlib.metadata.EntryPoint("wrong", "dsage_ray.domains.maze.plugin:DOMAIN", group),
                      importlib.metadata.EntryPoint("broken", "no_such_package.plugin:DOMAIN", group))
    with pytest.raises(InputError, match="entry point 'dsage_ray.domains.maze.plugin:DOMAIN' must name a DomainSpec "
                                         "with name='wrong'"):
        get_domain("wrong")
    with pytest.raises(InputError, match="domain 'broken': cannot load entry point .*No module named 'no_such_package'"):
        RunConfig.build({"domain": "broken"})
