"""Agent kinds as plug-ins: the ``dsage_ray.agents`` entry-point group, read lazily, with clear errors.

The pool test (tests/ray/test_agent_plugins.py) shows that a kind from an installed package also loads
inside Ray's simulator actors.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

from dsage_ray import agent_registry, plugins
from dsage_ray.agents import Agent, AgentError, load_agent, loader
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.builtin import RandomAgent
from dsage_ray.errors import InputError, describe

ROOT = Path(__file__).resolve().parents[2]
NOT_CALLABLE = 42


class Fixed(Agent):
    def initial_state(self, batch_size):
        return None

    def act(self, obs, state, rng):
        return np.zeros(len(obs["direction"]), dtype=np.int64), state


def fake_factory(target, options):
    return Fixed()


def entry(name: str, value: str) -> metadata.EntryPoint:
    return metadata.EntryPoint(name=name, value=value, group=loader.ENTRY_POINT_GROUP)


def with_entry_points(monkeypatch, *entries: metadata.EntryPoint) -> None:
    monkeypatch.setattr(agent_registry, "installed_kinds", lambda: plugins.collect(entries))


def test_dsage_ray_declares_its_own_kinds_in_its_table_not_as_entry_points():
    entry_points = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    assert loader.ENTRY_POINT_GROUP not in entry_points
    assert set(agent_registry.BUILTIN_KINDS) == {"python", "qtable", "random", "rllib", "sb3", "torchscript"}
    # An older install's metadata may still declare dsage_ray's kinds there: they are not plug-ins.
    assert all(plugins.provider(e) != plugins.OWN_DISTRIBUTION for e in agent_registry.installed_kinds().points.values())


def test_listing_kinds_imports_no_kind_nor_torch_or_ray():
    code = ("import sys; from dsage_ray.agents.loader import agent_kinds; kinds = agent_kinds(); "
            "assert {'python', 'random', 'rllib', 'sb3', 'torchscript'} <= set(kinds), kinds; "
            "from dsage_ray.domains import get_domain; maze = get_domain('maze').agents.kinds(); "
            "assert {'builtin', 'dcd', 'rllib', 'torchscript'} <= set(maze), maze; "
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'ray') "
            "or m.startswith(('dsage_ray.domains.maze.agents.dcd', 'dsage_ray.agents.rllib', 'dsage_ray.agents.torchscript'))); "
            "assert not heavy, heavy")
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, timeout=120)


def test_built_in_kinds_load_without_the_install_metadata(monkeypatch):
    with_entry_points(monkeypatch)  # a source checkout on PYTHONPATH: no entry points at all
    assert isinstance(load_maze_agent("builtin:random"), RandomAgent)
    assert set(loader.agent_kinds()) >= {"python", "random", "rllib", "sb3", "torchscript"}


def test_a_factory_taking_the_spaces_gets_them_and_a_two_argument_one_still_loads(monkeypatch):
    seen = {}

    def spaced_factory(target, options, *, observation_space, action_space, env=None):
        seen.update(observation_space=observation_space, action_space=action_space, env=env)
        return Fixed()

    monkeypatch.setitem(agent_registry.REGISTERED, "spaced_kind", spaced_factory)
    monkeypatch.setitem(agent_registry.REGISTERED, "old_kind", fake_factory)
    assert isinstance(load_agent("spaced_kind:x", observation_space="obs", action_space="act"), Fixed)
    assert seen == {"observation_space": "obs", "action_space": "act", "env": None}
    assert isinstance(load_maze_agent("old_kind:x"), Fixed)


def test_unknown_kind_is_an_input_error_listing_the_known_kinds(monkeypatch):
    with_entry_points(monkeypatch, entry("vendor_kind", f"{__name__}:fake_factory"))
    with pytest.raises(AgentError) as info:
        load_maze_agent("nonsense:foo")
    message = str(info.value)
    assert isinstance(info.value, InputError) and describe(info.value)[0] == 2
    assert "unknown kind 'nonsense' (known: builtin, dcd, python, qtable, random, rllib, sb3, torchscript, vendor_kind;" in message
    assert "'dsage_ray.agents' entry-point group" in message and "\n" not in message


def test_an_entry_point_kind_loads_its_factory_only_when_used(monkeypatch):
    with_entry_points(monkeypatch, entry("vendor_kind", f"{__name__}:fake_factory"))
    assert loader.agent_kinds()["vendor_kind"] == f"{__name__}:fake_factory"
    agent = load_maze_agent("vendor_kind:anything")
    assert isinstance(agent, Fixed) and agent.spec == "vendor_kind:anything"


def test_a_kind_registered_in_this_process_wins(monkeypatch):
    with_entry_points(monkeypatch, entry("vendor_kind", "no_such_module:factory"))
    monkeypatch.setitem(agent_registry.REGISTERED, "vendor_kind", fake_factory)
    assert isinstance(load_maze_agent("vendor_kind:x"), Fixed)
    assert loader.agent_kinds()["vendor_kind"] == "registered in this process"


@pytest.mark.parametrize("entries, needle", [
    ([entry("vendor_kind", "no_such_module:factory")],
     "kind 'vendor_kind' (no_such_module:factory, from an installed package) cannot be loaded: ModuleNotFoundError"),
    ([entry("vendor_kind", f"{__name__}:NOT_CALLABLE")], "is not a callable factory(target, options)"),
    ([entry("vendor_kind", f"{__name__}:fake_factory"), entry("vendor_kind", "other.module:factory")],
     "kind 'vendor_kind' is provided by more than one installed package"),
])
def test_broken_or_conflicting_plug_ins_fail_in_one_line(monkeypatch, entries, needle):
    with_entry_points(monkeypatch, *entries)
    with pytest.raises(AgentError) as info:
        load_maze_agent("vendor_kind:x")
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_an_installed_package_provides_a_kind(agent_plugin):
    from tests.plugin_package import DIST_NAME, MODULE

    assert agent_plugin not in agent_registry.REGISTERED  # nothing registered by hand: found through the metadata
    sys.modules.pop(MODULE, None)
    assert loader.agent_kinds()[agent_plugin] == f"{MODULE}:load_constant_agent"
    assert MODULE not in sys.modules  # listing imported nothing
    agent = load_maze_agent(f"{agent_plugin}:forward")
    assert type(agent).__module__ == MODULE and agent.spec == f"{agent_plugin}:forward"
    with pytest.raises(AgentError, match="unknown action"):
        load_maze_agent(f"{agent_plugin}:jump")
    (found,) = [e for e in metadata.entry_points(group=loader.ENTRY_POINT_GROUP) if e.name == agent_plugin]
    assert found.dist.name == DIST_NAME
