"""Warm starts (``surrogate.init``) and pretrained surrogates (``dsage-ray surrogate pretrain``)."""

from pathlib import Path

import numpy as np
import pytest
import torch

import dsage_ray
from dsage_ray.cli import main
from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core.checkpoint import CHECKPOINT_NAME, save_checkpoint
from dsage_ray.core.runner import DSAGE
from dsage_ray.core.warm_start import (SurrogateInitError, check_warm_start, load_warm_start, pretrain)
from tests.fakes import SMALL_RUN, BitmapDomain

#: A real Maze run small enough for a test: the pretraining and CLI tests need a real domain's encoding. No
#: TensorBoard images: they cost seconds a set and no test here reads them.
MAZE_RUN = {"preset": "tiny", "maze.agent": "builtin:wall_follower", "budget": 60, "n_rand": 30, "maze.episodes": 2,
            "qd.exploit_iterations": 3, "surrogate.epochs": 2, "selection.count": 20, "image_every": 0}


def bitmap_runner(**overrides) -> DSAGE:
    return DSAGE(config=RunConfig.build({**SMALL_RUN, **overrides}), domain=BitmapDomain())


@pytest.fixture(scope="module")
def cold_checkpoint(tmp_path_factory) -> tuple[Path, dict]:
    """A finished cold Bitmap run's checkpoint file and its state."""
    runner = bitmap_runner(seed=3)
    runner.run()
    state = runner.state_dict()
    return save_checkpoint(state, tmp_path_factory.mktemp("cold") / CHECKPOINT_NAME), state


@pytest.fixture(scope="module")
def maze_run(tmp_path_factory) -> Path:
    """A finished tiny Maze run folder (a real surrogate run)."""
    out = tmp_path_factory.mktemp("maze") / "run"
    return dsage_ray.run(MAZE_RUN, local=True, out=out).path


def weights(model) -> list[np.ndarray]:
    return [t.detach().numpy().copy() for t in model.state_dict().values()]


def test_warm_start_loads_weights_and_prior_and_exploits_from_the_first_iteration(cold_checkpoint):
    path, state = cold_checkpoint
    runner = bitmap_runner(seed=5, **{"surrogate.init": str(path)})
    metrics = runner.step()
    prior = len(state["dataset"]["objective"])
    assert metrics["prior_samples"] == prior
    # The first batch came from the loaded model (it was predicted, so its error is reported) ...
    assert "mae_objective" in metrics and "time_exploit" in metrics
    # ... and its evaluations follow the prior in the dataset.
    assert len(runner.dataset) == prior + metrics["evaluated_this_iteration"]
    np.testing.assert_array_equal(runner.dataset.objective[:prior], state["dataset"]["objective"])
    # Nothing trained yet: the weights are the source's.
    for ours, theirs in zip(weights(runner.surrogate.model), state["surrogate"]["model"].values()):
        np.testing.assert_array_equal(ours, theirs.numpy())


def test_a_warm_run_without_its_prior_keeps_only_its_own_evaluations(cold_checkpoint):
    path, _ = cold_checkpoint
    runner = bitmap_runner(seed=5, **{"surrogate.init": str(path), "experimental.init_prior": False})
    metrics = runner.step()
    assert metrics["prior_samples"] == 0
    assert len(runner.dataset) == metrics["evaluated_this_iteration"]


def test_a_warm_run_is_reproducible_and_resumes_exactly(cold_checkpoint):
    path, _ = cold_checkpoint
    overrides = {"seed": 5, "surrogate.init": str(path)}
    whole = bitmap_runner(**overrides)
    whole.run()
    first = bitmap_runner(**overrides)
    first.step()
    saved = first.state_dict()
    resumed = bitmap_runner(**overrides)
    resumed.load_state_dict(saved)
    resumed.run()
    for key in ("qd_score", "evals", "surrogate_loss", "mae_objective", "prior_samples"):
        assert [row.get(key) for row in resumed.history] == [row.get(key) for row in whole.history], key
    np.testing.assert_array_equal(np.sort(resumed.archive.data("objective")), np.sort(whole.archive.data("objective")))
    assert resumed.proposer.prior_samples == whole.proposer.prior_samples > 0


def test_a_warm_start_differs_from_a_cold_one(cold_checkpoint):
    path, _ = cold_checkpoint
    cold = bitmap_runner(seed=5)
    warm = bitmap_runner(seed=5, **{"surrogate.init": str(path)})
    cold.step(), warm.step()
    assert cold.history[0]["evaluated_this_iteration"] == SMALL_RUN["n_rand"]
    assert "mae_objective" not in cold.history[0]
    assert not np.array_equal(cold.dataset.levels()[:5], warm.dataset.levels()[-5:])


def test_the_init_path_is_made_absolute_when_the_config_is_built(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    config = RunConfig.build({**SMALL_RUN, "surrogate.init": "runs/old"})
    assert config.surrogate.init == str(tmp_path / "runs" / "old")
    with pytest.raises(ConfigError, match="surrogate.init: a warm start needs a surrogate"):
        RunConfig.build({**SMALL_RUN, "variant": "map_elites", "surrogate.init": "x"})


@pytest.mark.parametrize("key, value", [("surrogate.channels", 8), ("variant", "dsage_basic")])
def test_a_source_of_another_network_is_refused_naming_the_key(cold_checkpoint, key, value):
    path, state = cold_checkpoint
    source = load_warm_start(path)
    config = RunConfig.build({**SMALL_RUN, key: value, "surrogate.init": str(path)})
    expected = "surrogate.kind" if key == "variant" else key
    with pytest.raises(SurrogateInitError, match=f"trained with {expected}="):
        source.check_compatible(config, level_shape=state["dataset"]["level_shape"])
    with pytest.raises(SurrogateInitError, match="encoded as"):
        source.check_compatible(RunConfig.build(SMALL_RUN), level_shape=(5, 8, 8))


def test_bad_sources_are_refused_in_one_line(tmp_path, cold_checkpoint):
    with pytest.raises(SurrogateInitError, match="no such file or folder"):
        load_warm_start(tmp_path / "missing")
    with pytest.raises(SurrogateInitError, match="a folder without a run checkpoint"):
        load_warm_start(tmp_path)
    corrupt = tmp_path / "corrupt.surrogate"
    corrupt.write_bytes(b"not a checkpoint at all")
    with pytest.raises(SurrogateInitError, match="corrupt.surrogate"):
        load_warm_start(corrupt)
    runner = bitmap_runner(variant="map_elites")
    runner.run()
    direct = save_checkpoint(runner.state_dict(), tmp_path / "me" / CHECKPOINT_NAME)
    with pytest.raises(SurrogateInitError, match="a run without a surrogate"):
        load_warm_start(direct.parent)
    _, state = cold_checkpoint
    foreign = save_checkpoint({"something": 1}, tmp_path / "foreign.surrogate")
    with pytest.raises(SurrogateInitError, match="not a surrogate checkpoint"):
        load_warm_start(foreign)


def test_pretraining_fits_every_level_and_warm_starts_a_real_run(maze_run, tmp_path):
    source = load_warm_start(maze_run)  # a run folder
    assert source.path == maze_run / CHECKPOINT_NAME and source.levels > 0
    ticks = []
    result = pretrain(sources=[source, source], config=source.config, out=tmp_path / "p.surrogate", epochs=2,
                      progress=lambda epoch, total: ticks.append((epoch, total)))
    assert ticks == [(1, 2), (2, 2)]
    again = load_warm_start(result.path)
    assert again.levels == 2 * source.levels
    assert again.info["epochs"] == 2
    assert set(again.info["held_out_spearman"]) == {"objective", *source.config.maze.measures}
    assert again.agent == source.config.maze.agent
    # The pretrained network differs from the run's own (fresh weights, trained on all levels).
    assert any(not torch.equal(a, b) for a, b in zip(again.surrogate["model"].values(),
                                                      source.surrogate["model"].values()))
    # A few warm iterations (15 evaluations) show the run starts from the prior and spends its budget; a warm run
    # exploits from its first iteration, so n_rand is only the floor the config checks the budget against.
    warm = dsage_ray.run(MAZE_RUN, overrides={"surrogate.init": str(result.path), "seed": 1, "budget": 15,
                                              "n_rand": 15}, local=True, out=tmp_path / "warm")
    assert warm.metrics[0]["prior_samples"] == again.levels and len(warm.metrics) > 1
    assert warm.metrics[-1]["evals"] == 15


def test_preflight_refuses_a_mismatched_warm_start_before_any_evaluation(maze_run, tmp_path):
    config = RunConfig.build({**MAZE_RUN, "surrogate.channels": 8, "surrogate.init": str(maze_run)})
    with pytest.raises(SurrogateInitError, match="surrogate.channels"):
        check_warm_start(config)
    with pytest.raises(dsage_ray.InputError, match="surrogate.channels"):
        dsage_ray.run(config, local=True, out=tmp_path / "never")
    assert not (tmp_path / "never").exists()


def test_the_cli_pretrains_describes_and_refuses_bad_arguments(maze_run, tmp_path, capsys):
    out = tmp_path / "cli.surrogate"
    assert main(["surrogate", "pretrain", "--from", str(maze_run), "--out", str(out), "--epochs", "1"]) == 0
    printed = capsys.readouterr().out
    assert f"pretrained surrogate: {out}" in printed and "--surrogate-init" in printed
    assert main(["surrogate", "info", str(out)]) == 0
    assert "held-out Spearman" in capsys.readouterr().out
    assert main(["surrogate", "pretrain", "--out", str(out)]) == 2
    assert "either --from" in capsys.readouterr().err
    assert main(["surrogate", "pretrain", "--agent", "builtin:random", "--out", str(out)]) == 2
    assert "--levels" in capsys.readouterr().err
    assert main(["surrogate", "info", str(tmp_path / "nothing")]) == 2
    assert "no such file or folder" in capsys.readouterr().err


def test_pretrain_surrogate_is_public_and_takes_paths_and_keys(maze_run, tmp_path):
    result = dsage_ray.pretrain_surrogate([maze_run], out=tmp_path / "api.surrogate",
                                          overrides={"surrogate.epochs": 1, "surrogate.lr": 5e-4})
    assert result.info["epochs"] == 1 and result.config.surrogate.lr == 5e-4
    assert load_warm_start(tmp_path / "api.surrogate").levels == load_warm_start(maze_run).levels
    with pytest.raises(SurrogateInitError, match="no source"):
        dsage_ray.pretrain_surrogate([], out=tmp_path / "none.surrogate")
    assert not (tmp_path / "none.surrogate").exists()
