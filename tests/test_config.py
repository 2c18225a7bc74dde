"""Config validation: names come from one table per kind, and a near miss gets a "did you mean"."""

from __future__ import annotations

import typing

import pytest

from dsage_ray.config import (PRESETS, VARIANTS, ConfigError, EmitterName, MazeObjective, RunConfig,
                              SelectionMethod)


@pytest.mark.parametrize("names, table", [
    (EmitterName, ("dsage_ray.qd.optimizer", "EMITTERS")),
    (SelectionMethod, ("dsage_ray.qd.selection", "SELECTION_METHODS")),
    (MazeObjective, ("dsage_ray.domains.maze.measures", "OBJECTIVES")),
])
def test_each_config_name_set_is_its_tables_keys(names, table):
    """The config's Literal (checked without importing pyribs) and the table that implements it agree."""
    import importlib

    module, attribute = table
    assert list(typing.get_args(names)) == list(getattr(importlib.import_module(module), attribute))


@pytest.mark.parametrize("values, message", [
    ({"qd.emitter": "map_elite"},
     "qd.emitter: must be 'map_elites', 'cma_me' or 'random' (got 'map_elite'; did you mean 'map_elites'?)"),
    ({"selection.method": "downsampled"},
     "selection.method: must be 'downsample', 'random' or 'full' (got 'downsampled'; did you mean 'downsample'?)"),
    ({"maze.objective": "failure"}, "(got 'failure'; did you mean 'failure_rate'?)"),
    ({"domain": "mario", "mario.objective": "incompleted"}, "(got 'incompleted'; did you mean 'incompletion'?)"),
    ({"surrogate.kind": "twostage"}, "surrogate.kind: must be 'two_stage', 'one_stage' or 'none' (got 'twostage'; "
                                     "did you mean 'two_stage'?)"),
    ({"surrogate.epoch": 5}, "surrogate.epoch: unknown config key (did you mean surrogate.epochs"),
    ({"surrogat.epochs": 5}, "surrogat: unknown config section (known: maze, mario, surrogate, qd, selection, ray); "
                             "did you mean 'surrogate'?"),
    ({"variant": "dsage_basc"}, "; did you mean 'dsage_basic'?"),
    ({"preset": "tiney"}, "; did you mean 'tiny'?"),
])
def test_unknown_names_suggest_the_closest(values, message):
    with pytest.raises(ConfigError) as error:
        RunConfig.build(values)
    assert message in str(error.value)


def test_a_name_far_from_all_gets_no_guess():
    with pytest.raises(ConfigError) as error:
        RunConfig.build({"qd.emitter": "xyz"})
    assert "did you mean" not in str(error.value) and "(got 'xyz')" in str(error.value)


def test_validate_checks_names_set_as_attributes():
    config = RunConfig()
    config.selection.method = "ful"
    with pytest.raises(ConfigError, match=r"selection.method: .* \(got 'ful'; did you mean 'full'\?\)"):
        config.validate()


def test_every_preset_and_variant_is_valid():
    for domain, presets in PRESETS.items():
        for preset in presets:
            for variant in VARIANTS[domain]:
                config = RunConfig.build({"domain": domain, "preset": preset, "variant": variant})
                assert (config.domain, config.preset, config.variant) == (domain, preset, variant)


def test_runtime_lookups_use_the_same_tables():
    """Code handed an unchecked name (no config) fails the same way, with the same suggestion."""
    import numpy as np

    from dsage_ray.qd.selection import select_solutions

    with pytest.raises(ConfigError, match="unknown method 'ful' .*did you mean 'full'"):
        select_solutions(None, method="ful", block=(1,), count=1, rng=np.random.default_rng(0))
