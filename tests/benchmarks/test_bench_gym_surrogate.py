"""benchmarks/bench_gym_surrogate.py: two-stage against one-stage on synthetic gym levels whose answer is known."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_gym_surrogate as bench  # noqa: E402


def gym_config(**surrogate):
    from dsage_ray.config import RunConfig

    # The behaviour map the benchmark was written for (the shipped space maps two parameters).
    return RunConfig.build({"domain": "gym", "preset": "demo", "gym.space": "cartpole", "gym.measures": ("x_end", "length"),
                            **{f"surrogate.{key}": value for key, value in surrogate.items()}})


def synthetic(n: int, config, seed: int = 0) -> bench.SearchData:
    """Levels of the CartPole space whose objective, measures and occupancy are exact functions of the parameters."""
    from dsage_ray.domains import build_domain

    domain = build_domain(config)
    rng = np.random.default_rng(seed)
    levels = domain.encode(domain.random_solutions(n, rng))
    units = levels[:, :, 0, 0].astype(np.float64)
    objective = (units[:, 0] + 1) / 2  # in [0, 1], like a failure rate
    # x_end, and a length of the same scale: with raw targets in the hundreds (a real episode length) the length would
    # drive the loss (docs/results/gym_audit, the surrogate section)
    measures = np.stack([2.0 * units[:, 1], 2.0 + units[:, 2]], axis=1)
    height, width = domain.occupancy_shape
    rows = np.clip(((units[:, 3] + 1) / 2 * height).astype(int), 0, height - 1)
    occupancy = np.zeros((n, height, width), np.float32)
    occupancy[np.arange(n), rows, width // 2] = 1.0
    return bench.SearchData(name="synthetic", levels=levels, objective=objective, measures=measures,
                            occupancy=occupancy, domain=domain, surrogate_config=config.surrogate)


def test_both_models_rank_a_target_that_is_a_function_of_the_parameters():
    data = synthetic(240, gym_config(epochs=40, batch_size=32, lr=0.003))
    (train, test), = bench.splits(len(data.objective), count=1, test_share=0.25, seed=1)
    assert len(test) == 60 and not set(train) & set(test)
    for kind in bench.KINDS:
        scores = bench.fit_and_score(data, kind, train, test, seed=0, predict_levels=data.levels[:64])
        assert scores["objective ρ"] > 0.9, (kind, scores)
        assert scores["x_end ρ"] > 0.9 and scores["length ρ"] > 0.9, (kind, scores)
        assert scores["predict levels/s"] > 0 and scores["train CPU s"] > 0
        assert ("occupancy MAE" in scores) == (kind == "two_stage")
    # The truth against itself, and a constant prediction, score as the docstring says.
    assert bench.spearman(data.objective, data.objective) == pytest.approx(1.0)
    assert bench.spearman(np.zeros(5), np.arange(5.0)) == 0.0
    assert np.isnan(bench.spearman(np.arange(5.0), np.ones(5)))


def search_folder(root: Path, name: str, *, finished: bool = True, with_dataset: bool = True,
                  seed: int = 0) -> Path:
    """A search folder as an audit leaves it: config.json, a checkpoint with the surrogate dataset, a collection."""
    from dsage_ray.core.checkpoint import save_checkpoint

    config = gym_config(epochs=2, batch_size=16)
    data = synthetic(40, config, seed)
    folder = root / name / "search"
    folder.mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps(config.to_dict()))
    state = data.subset_state(np.arange(40)) if with_dataset else None
    save_checkpoint({"config": config.to_dict(), "dataset": state}, folder / "checkpoint.dsage")
    if finished:
        (root / name / "collection").mkdir()
        (root / name / "collection" / "collection.json").write_text("{}")
    return folder


def test_a_parent_folder_benches_its_finished_searches(tmp_path, capsys):
    search_folder(tmp_path, "dsage_seed1")
    search_folder(tmp_path, "dsage_seed2", seed=1)
    search_folder(tmp_path, "dsage_seed3", finished=False)
    search_folder(tmp_path, "map_elites_seed1", with_dataset=False)
    results = bench.main([str(tmp_path), "--splits", "2", "--predict-levels", "16"])
    assert [r.data.name for r in results] == ["dsage_seed1", "dsage_seed2"]
    assert all(len(r.per_split[kind]) == 2 for r in results for kind in bench.KINDS)
    out = capsys.readouterr().out
    assert "dsage_seed3/search: audit not finished" in out
    assert "map_elites_seed1/search: no surrogate dataset" in out
    for name in ("dsage_seed1", "dsage_seed2"):
        for model in ("two-stage", "one-stage", "two − one"):
            assert re.search(rf"^{name}\s+{model}\s+[-+]?\d", out, re.M), out
    assert re.search(r"^2 searches\s+two − one", out, re.M)
    assert "within two s.e.:" in out and "32 train / 8 test levels" in out


def test_a_folder_without_a_checkpoint_is_refused_in_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit) as raised:
        bench.main([str(tmp_path / "empty")])
    message = str(raised.value)
    assert message.startswith("error: ") and "no checkpoint.dsage" in message and "\n" not in message
    # A named search without a surrogate dataset is refused too (not skipped).
    plain = search_folder(tmp_path, "map_elites_seed1", with_dataset=False)
    with pytest.raises(SystemExit, match="no surrogate dataset"):
        bench.main([str(plain)])
