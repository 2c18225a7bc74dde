"""Config validation: names come from one table per kind, and a near miss gets a "did you mean"."""

from __future__ import annotations

import typing

import pytest

from dsage_ray.config import (ConfigError, EmitterName, MutatingEmitter, RunConfig, SelectionMethod, SurrogateKind,
                               presets, variants)
from dsage_ray.domains import domain_names
from dsage_ray.domains.maze.plugin import MazeObjective


@pytest.mark.parametrize("names, table", [
    (EmitterName, ("dsage_ray.qd.optimizer", "EMITTERS")),
    (SelectionMethod, ("dsage_ray.qd.selection", "SELECTION_METHODS")),
    (MutatingEmitter, ("dsage_ray.qd.mutants", "MUTATIONS")),
    (MazeObjective, ("dsage_ray.domains.maze.measures", "OBJECTIVES")),
])
def test_each_config_name_set_is_its_tables_keys(names, table):
    """The config's Literal (checked without importing pyribs) and the table that implements it agree."""
    import importlib

    module, attribute = table
    assert list(typing.get_args(names)) == list(getattr(importlib.import_module(module), attribute))


def test_surrogate_kinds_are_the_model_table_plus_none():
    from dsage_ray.surrogate.surrogate import MODELS

    assert list(typing.get_args(SurrogateKind)) == [*MODELS, "none"]


@pytest.mark.parametrize("values, message", [
    ({"qd.emitter": "map_elite"},
     "qd.emitter: must be 'map_elites', 'cma_me', 'random', 'gaussian', 'halton' or 'cross_entropy' (got 'map_elite'; "
     "did you mean 'map_elites'?)"),
    ({"selection.method": "downsampled"},
     "selection.method: must be 'downsample', 'random' or 'full' (got 'downsampled'; did you mean 'downsample'?)"),
    ({"maze.objective": "failure"}, "(got 'failure'; did you mean 'failure_rate'?)"),
    ({"domain": "mario", "mario.objective": "incompleted"}, "(got 'incompleted'; did you mean 'incompletion'?)"),
    ({"surrogate.kind": "twostage"}, "surrogate.kind: must be 'two_stage', 'one_stage' or 'none' (got 'twostage'; "
                                     "did you mean 'two_stage'?)"),
    ({"surrogate.epoch": 5}, "surrogate.epoch: unknown config key (did you mean surrogate.epochs"),
    # DOMAINS: every installed domain's name, in the registry's order (a user's plug-ins too).
    ({"surrogat.epochs": 5}, "surrogat: unknown config section (known: DOMAINS, surrogate, qd, selection, ray, "
                             "experimental); did you mean 'surrogate'?"),
    ({"marioo.runs": 1}, "marioo: unknown config section (known: DOMAINS, surrogate, "),
    ({"domain": "mazes"}, "domain: unknown domain 'mazes' (known: DOMAINS)"),
    ({"domain": "mazes"}, "; did you mean 'maze'?"),
    ({"variant": "dsage_basc"}, "; did you mean 'dsage_basic'?"),
    ({"preset": "tiney"}, "; did you mean 'tiny'?"),
])
def test_unknown_names_suggest_the_closest(values, message):
    assert {"gym", "mario", "maze"} <= set(domain_names())
    with pytest.raises(ConfigError) as error:
        RunConfig.build(values)
    assert message.replace("DOMAINS", ", ".join(domain_names())) in str(error.value)


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
    for domain in ("maze", "mario"):
        for preset in presets(domain):
            for variant in variants(domain):
                config = RunConfig.build({"domain": domain, "preset": preset, "variant": variant})
                assert (config.domain, config.preset, config.variant) == (domain, preset, variant)


@pytest.mark.parametrize("domain", ["maze", "mario", "gym"])
def test_a_preset_sets_no_key_that_the_dsage_variant_overrides(domain):
    """A variant is layered over the preset, so such a preset key never runs (the gym presets once set a ``top``
    pick that no DSAGE audit used)."""
    dsage = variants(domain)["dsage"]
    for preset, keys in presets(domain).items():
        overridden = {key: (keys[key], dsage[key]) for key in keys.keys() & dsage.keys() if keys[key] != dsage[key]}
        assert not overridden, f"{domain} preset {preset!r}: (preset's, dsage's) {overridden}"


def test_runtime_lookups_use_the_same_tables():
    """Code handed an unchecked name (no config) fails the same way, with the same suggestion."""
    import numpy as np

    from dsage_ray.qd.selection import select_solutions

    with pytest.raises(ConfigError, match="unknown method 'ful' .*did you mean 'full'"):
        select_solutions(None, method="ful", block=(1,), count=1, rng=np.random.default_rng(0))


def test_a_config_holds_its_own_domain_section_and_round_trips():
    """Only the run's domain has a section (another's appears when one of its keys is given)."""
    mario = RunConfig.build({"domain": "mario", "preset": "tiny"})
    assert set(mario.sections) == {"mario"} and not any(key.startswith("maze.") for key in mario.to_flat())
    assert mario.domain_config is mario.mario and mario.mario.runs == 1
    with pytest.raises(AttributeError, match="no 'maze' section in this 'mario' config"):
        mario.maze
    both = RunConfig.build({"maze.episodes": 3, "mario.runs": 2})
    assert (both.maze.episodes, both.mario.runs, list(both.sections)) == (3, 2, ["maze", "mario"])
    flat = both.to_flat()
    assert flat["maze.episodes"] == 3 and RunConfig.build(flat) == both
    # Domain sections sit where Maze and Mario did: after the scalars, before the core sections.
    assert list(both.to_dict())[-7:] == ["maze", "mario", "surrogate", "qd", "selection", "ray", "experimental"]


def test_a_domain_section_round_trips_through_toml_and_json(tmp_path):
    import json

    config = RunConfig.build({"domain": "maze", "preset": "tiny", "maze.archive_dims": [8, 4]})
    (tmp_path / "c.json").write_text(json.dumps(config.to_dict()))
    toml = "\n".join(f"{key} = {json.dumps(value)}" for key, value in config.to_flat().items()
                     if not isinstance(value, list) or all(not isinstance(v, list) for v in value))
    (tmp_path / "c.toml").write_text(toml)
    assert RunConfig.from_file(tmp_path / "c.json") == config
    assert RunConfig.from_file(tmp_path / "c.toml").maze.archive_dims == (8, 4)


def test_the_built_in_domains_are_registered_entry_points():
    assert {"maze", "mario"} <= set(domain_names())


def test_occupancy_sum_measure_needs_a_model_that_predicts_occupancy():
    with pytest.raises(ConfigError, match="surrogate.occupancy_sum_measure"):
        RunConfig.build({"variant": "dsage", "surrogate.kind": "one_stage",
                         "surrogate.occupancy_sum_measure": "mean_path_length"})
    with pytest.raises(ConfigError, match="surrogate.occupancy_sum_measure"):
        RunConfig.build({"variant": "dsage_basic", "surrogate.occupancy_sum_measure": "mean_path_length"})
    built = RunConfig.build({"variant": "dsage", "surrogate.occupancy_sum_measure": "mean_path_length"})
    assert built.surrogate.occupancy_sum_measure == "mean_path_length"


def test_time_budget_is_a_validated_float_key_that_round_trips():
    assert RunConfig.build({}).time_budget == 0.0  # no limit
    config = RunConfig.build({"preset": "tiny", "time_budget": 600})
    assert config.time_budget == 600.0 and isinstance(config.time_budget, float)
    assert config.to_flat()["time_budget"] == 600.0 and RunConfig.build(config.to_flat()) == config
    # A flat key like any other: a Tune grid axis.
    assert config.replace(time_budget=90.0).time_budget == 90.0
    with pytest.raises(ConfigError, match=r"^time_budget: must be >= 0 seconds \(0: no limit\) \(got -1.0\)$"):
        RunConfig.build({"time_budget": -1})
    with pytest.raises(ConfigError, match="time_budget: expected a number, got '10m'"):
        RunConfig.build({"time_budget": "10m"})


@pytest.mark.parametrize("name", ["/tmp/elsewhere", "../outside", "runs/../../outside", ""])
def test_a_run_name_cannot_leave_the_runs_folder(name):
    with pytest.raises(ConfigError, match="name: must be a relative folder name without '..'"):
        RunConfig.build({"name": name})


def test_a_renamed_key_still_reads_under_its_old_name():
    """Keys moved into ``experimental``, as the records' commands (docs/results/) still name them."""
    config = RunConfig.build({"surrogate.holdout_levels": 7, "selection.screen_pool": 2.0})
    assert (config.experimental.holdout_levels, config.experimental.screen_pool) == (7, 2.0)
    assert "surrogate.holdout_levels" not in config.to_flat()


def test_a_removed_key_loads_at_the_value_that_runs_now_and_is_refused_with_its_reason_otherwise():
    from dsage_ray.config import REMOVED_KEYS

    stored = RunConfig.build({}).to_flat() | {"selection.cost_offset": 200, "image_levels": 3}
    assert RunConfig.build(stored) == RunConfig.build({})
    with pytest.raises(ConfigError, match=r"selection.cost_offset: this key was removed \(the screen's cost model"):
        RunConfig.build({"selection.cost_offset": 74})
    assert not REMOVED_KEYS.keys() & RunConfig.build({}).to_flat().keys()


def test_a_key_gone_without_a_record_that_needs_it_is_an_unknown_key_with_the_closest_current_ones():
    with pytest.raises(ConfigError, match=r"selection.gain_window: unknown config key \(did you mean "
                                          r"experimental.gain_window"):
        RunConfig.build({"selection.gain_window": 4})
