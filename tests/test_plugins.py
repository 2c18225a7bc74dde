"""``dsage_ray.plugins``: one group's entry points by name, dsage_ray's own first, clashes kept aside."""

from __future__ import annotations

from importlib import metadata

from dsage_ray import plugins


def point(name: str, value: str) -> metadata.EntryPoint:
    return metadata.EntryPoint(name=name, value=value, group="dsage_ray.test")


def test_names_map_to_their_entry_point_and_a_repeated_declaration_is_no_clash():
    found = plugins.collect([point("a", "pkg_a:A"), point("b", "pkg_b:B"), point("a", "pkg_a:A")])
    assert {name: p.value for name, p in found.points.items()} == {"a": "pkg_a:A", "b": "pkg_b:B"}
    assert found.clashes == {}


def test_two_values_for_one_name_are_a_clash_listing_both():
    found = plugins.collect([point("a", "pkg_a:A"), point("a", "pkg_b:A"), point("b", "pkg_b:B")])
    assert [p.value for p in found.clashes["a"]] == ["pkg_a:A", "pkg_b:A"]
    assert set(found.clashes) == {"a"} and found.points["a"].value == "pkg_a:A"
    assert plugins.describe(found.points["a"]) == "pkg_a:A (an installed package)"


def test_the_installed_domains_hold_dsage_rays_own_first():
    # The agent kinds' group holds plug-ins only: dsage_ray's own kinds are its table (dsage_ray.agent_registry).
    own = {"maze", "mario", "gym"}
    found = plugins.scan("dsage_ray.domains")
    assert own <= set(found.points)
    first = list(found.points)[:len(own)]
    assert all(plugins.provider(found.points[name]) == "dsage_ray" for name in first), first
