"""``--grid KEY=V1,V2``: parsing, the axes of an ablation, Tune's param space, and errors before Ray starts.

Nothing here starts Ray: ``dsage-ray ablate`` is run with the cluster calls replaced by recorders.
"""

from __future__ import annotations

import pytest

from dsage_ray.cli import main
from dsage_ray.config import ConfigError, RunConfig, paper_comparison
from dsage_ray.ray import launch as ray_launch
from dsage_ray.ray.experiment import ablation_axes, grid_configs, grid_param_space, parse_grid
from dsage_ray.results import ExperimentResult

CONFIG = "experiments/configs/maze_dsage.toml"


def test_values_are_read_like_set_values_and_commas_inside_brackets_or_quotes_stay():
    assert parse_grid("seed=0,1,2") == ("seed", [0, 1, 2])
    assert parse_grid("variant = dsage, map_elites") == ("variant", ["dsage", "map_elites"])
    assert parse_grid("selection.block=[4,3],[8,6]") == ("selection.block", [[4, 3], [8, 6]])
    assert parse_grid('name="a,b",c') == ("name", ["a,b", "c"])
    assert parse_grid("surrogate.lr=1e-3,0.01") == ("surrogate.lr", [0.001, 0.01])
    assert parse_grid("selection.screen_gain=true,false") == ("selection.screen_gain", [True, False])


def test_a_fault_spaces_search_keys_are_each_points_own_and_a_key_the_caller_set_stays():
    # The space fills them in for DSAGE (mutants, their step, auto); a MAP-Elites point gets none and is not refused.
    space = {"domain": "gym", "gym.space": "lunarlander_fault", "gym.agent": "builtin:random"}
    explicit, (dsage, map_elites) = grid_configs(RunConfig.build(space), {"variant": ["dsage", "map_elites"]})
    assert not {"selection.elite_mutants", "experimental.mutant_sigma", "experimental.min_predicted"} & set(explicit)
    assert (dsage.selection.elite_mutants, dsage.experimental.mutant_sigma) == (20, 0.01)
    assert (map_elites.selection.elite_mutants, map_elites.experimental.mutant_sigma) == (0, 0.0)
    # DSAGE runs as search = auto; MAP-Elites, which auto cannot start from, stays fixed.
    assert (dsage.search, map_elites.search) == ("auto", "fixed")
    explicit, configs = grid_configs(RunConfig.build({**space, "selection.elite_mutants": 5}), {"seed": [1, 2]})
    assert explicit["selection.elite_mutants"] == 5 and [c.selection.elite_mutants for c in configs] == [5, 5]
    explicit, configs = grid_configs(RunConfig.build({**space, "search": "fixed"}), {"seed": [1, 2]})
    assert explicit["search"] == "fixed" and [c.search for c in configs] == ["fixed", "fixed"]
    # Where auto cannot run (a pipelined run), the space does not ask for it.
    assert RunConfig.build({**space, "pipeline": True}).search == "fixed"


@pytest.mark.parametrize("text, message", [
    ("seed", "expected KEY=V1,V2"),
    ("seed=", "no empty value"),
    ("seed=0,,1", "no empty value"),
    ("seed=1,1", "value 1 given twice"),
])
def test_malformed_grids_are_one_error(text, message):
    with pytest.raises(ConfigError, match=message):
        parse_grid(text)


def test_axes_default_to_the_paper_grid_and_to_the_configs_variant_when_other_keys_vary():
    base = RunConfig.build(domain="maze", preset="tiny", variant="dsage_basic")
    assert ablation_axes(base) == {"variant": list(paper_comparison("maze")), "seed": [0, 1, 2, 3, 4]}
    assert ablation_axes(base, ["surrogate.epochs=1,2"], seeds=2) == {
        "surrogate.epochs": [1, 2], "variant": ["dsage_basic"], "seed": [0, 1]}
    # A seed axis alone keeps the paper's variants; seeds as a list or through --grid.
    assert ablation_axes(base, ["seed=3,4"])["variant"] == list(paper_comparison("maze"))
    assert ablation_axes(base, variants=["dr"], seeds=[7]) == {"variant": ["dr"], "seed": [7]}
    assert ablation_axes(base, ["variant=dsage,dr"], default_variants=["map_elites"])["variant"] == ["dsage", "dr"]
    with pytest.raises(ConfigError, match="--seeds and --grid seed=... both set the seeds"):
        ablation_axes(base, ["seed=0,1"], seeds=2)
    with pytest.raises(ConfigError, match="--variants and --grid variant=... both"):
        ablation_axes(base, ["variant=dsage"], variants=["dr"])
    with pytest.raises(ConfigError, match="--grid seed: given twice"):
        ablation_axes(base, ["seed=0", "seed=1"])


def test_param_space_has_a_grid_search_per_varying_axis_and_each_point_is_the_config_a_run_would_use():
    base = RunConfig.build({"domain": "maze", "preset": "tiny", "variant": "dsage", "surrogate.epochs": 3,
                            "qd.num_emitters": 5})
    axes = {"variant": ["dsage", "map_elites"], "selection.block": [[4, 3], [8, 6]], "seed": [1]}
    space = grid_param_space(base, axes)
    assert space["variant"] == {"grid_search": ["dsage", "map_elites"]}
    assert space["selection.block"] == {"grid_search": [[4, 3], [8, 6]]}
    assert space["seed"] == 1  # one value: a plain key, so trial names show only what varies
    # Explicit keys only: surrogate.kind comes from each point's variant, not from the base's.
    assert space["surrogate.epochs"] == 3 and "surrogate.kind" not in space
    _, configs = grid_configs(base, axes)
    assert [(c.variant, c.selection.block, c.surrogate.kind) for c in configs] == [
        ("dsage", (4, 3), "two_stage"), ("dsage", (8, 6), "two_stage"),
        ("map_elites", (4, 3), "none"), ("map_elites", (8, 6), "none")]
    # The same point built directly, as `dsage-ray run --set ...` would.
    assert configs[2] == RunConfig.build({"domain": "maze", "preset": "tiny", "variant": "map_elites",
                                          "surrogate.epochs": 3, "selection.block": [4, 3], "seed": 1})


@pytest.mark.parametrize("grid, message", [
    (["surogate.epochs=1,2"], "--grid surogate.epochs: unknown config key (did you mean surrogate.epochs"),
    (["bogus=1"], "--grid bogus: unknown config key (sections and keys: budget, "),
    (["domain=maze,mario"], "--grid domain: cannot be a grid axis"),
    (["surrogate.kind=two_stage,bad"], "grid point surrogate.kind='bad', seed=0: surrogate.kind: must be "
                                       "'two_stage', 'one_stage' or 'none' (got 'bad')"),
    (["variant=dsage,nope"], "grid point variant='nope', seed=0: variant: unknown variant 'nope' for domain "
                             "'maze' (known: ['dr', 'dsage'"),
    (["surrogate.epochs=2,x"], "grid point surrogate.epochs='x', seed=0: surrogate.epochs: expected an integer"),
])
def test_a_bad_key_or_value_is_one_line_naming_it_before_ray_starts(grid, message, monkeypatch, capsys):
    monkeypatch.setattr(ray_launch, "start_ray", _no_ray)
    assert main(["ablate", CONFIG, "--preset", "tiny", *(f"--grid={g}" for g in grid)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"dsage-ray ablate: error: {message}") and err.count("\n") == 1, err


def test_an_unknown_variant_in_variants_is_reported_before_ray_starts(monkeypatch, capsys):
    monkeypatch.setattr(ray_launch, "start_ray", _no_ray)
    assert main(["ablate", CONFIG, "--variants", "dsage,dsage_fast", "--seeds", "1"]) == 2
    assert "variant: unknown variant 'dsage_fast' for domain 'maze' (known: [" in capsys.readouterr().err


def test_ablate_hands_tune_the_grid_and_checks_every_distinct_placement(monkeypatch, tmp_path):
    calls = {}
    monkeypatch.setattr(ray_launch, "start_ray", lambda address: calls.setdefault("connect", address))
    monkeypatch.setattr(ray_launch, "check_resources", lambda *configs, **_: calls.setdefault("checked", configs))
    monkeypatch.setattr(ray_launch, "run_experiment",
                        lambda space, **kwargs: calls.setdefault("run", (space, kwargs)) and ExperimentResult(path=tmp_path, trials=()))
    assert main(["ablate", CONFIG, "--preset", "tiny", "--grid", "ray.num_workers=1,2", "--grid", "seed=0,1",
                 "--out", str(tmp_path)]) == 0
    space, kwargs = calls["run"]
    assert space["ray.num_workers"] == {"grid_search": [1, 2]} and space["seed"] == {"grid_search": [0, 1]}
    assert space["variant"] == "dsage"  # another key varies: the config's variant only
    assert kwargs["name"] == "maze_dsage"
    assert sorted(c.ray.num_workers for c in calls["checked"]) == [1, 1, 2, 2]


def _no_ray(*args, **kwargs):
    raise AssertionError("Ray was started before the grid was checked")
