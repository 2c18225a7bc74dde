"""benchmarks/maze_dataset.py and benchmarks/bench_surrogate_ceiling.py: the .npz format's checks, a run folder's
round trip through it, and the benchmark's last lines."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import maze_dataset  # noqa: E402
from maze_dataset import MazeData, MazeDatasetError  # noqa: E402

from dsage_ray.domains.maze.generator import random_valid_levels  # noqa: E402
from dsage_ray.domains.maze.paths import furthest_pairs  # noqa: E402

LAST_LINE = re.compile(r"N=(\d+): surrogate ρ (-?\d\.\d{3}) ± (\d\.\d{3}) \| optimal path ρ (-?\d\.\d{3}) ± "
                       r"(\d\.\d{3}) \| GBM ρ (-?\d\.\d{3}) ± (\d\.\d{3})")


def synthetic(n: int = 48, *, seed: int = 0) -> MazeData:
    """Random valid 16×16 levels whose "path length" is twice the optimal one (so its optimal-path ρ is 1)."""
    walls = np.stack([level.walls for level in random_valid_levels(n, seed=seed, density_range=(0.0, 0.6))])
    length = furthest_pairs(walls)[:, 2].astype(np.float32)
    rng = np.random.default_rng(seed)
    measures = np.stack([walls.reshape(n, -1).sum(axis=1).astype(np.float32), 2 * length], axis=1)
    occupancy = rng.random((n, 16, 16), dtype=np.float32) * ~walls
    return MazeData(walls=walls, measures=measures, measure_names=("num_walls", "mean_path_length"),
                    occupancy=occupancy)


def write(path: Path, arrays: dict) -> Path:
    np.savez(path, **arrays)
    return path


def test_a_saved_dataset_loads_back_unchanged(tmp_path):
    data = synthetic(12)
    data.retest = np.full_like(data.measures, np.nan)
    data.retest[3] = data.measures[3] + 1
    data.iteration = np.arange(12) // 4
    loaded = maze_dataset.load(maze_dataset.save(data, tmp_path / "d.npz"))
    np.testing.assert_array_equal(loaded.walls, data.walls)
    np.testing.assert_array_equal(loaded.measures, data.measures)
    np.testing.assert_array_equal(loaded.occupancy, data.occupancy)
    np.testing.assert_array_equal(loaded.retest, data.retest)
    np.testing.assert_array_equal(loaded.iteration, data.iteration)
    assert loaded.measure_names == data.measure_names
    # The walls are numpy.packbits of the row-major interior, as the format says.
    with np.load(tmp_path / "d.npz") as raw:
        assert raw["walls"].dtype == np.uint8 and raw["walls"].shape == (12, 32)
        np.testing.assert_array_equal(raw["walls"][5], np.packbits(data.walls[5].reshape(-1)))


def test_only_the_required_keys_are_needed_and_16x16_is_assumed(tmp_path):
    data = synthetic(5)
    arrays = data.arrays()
    path = write(tmp_path / "min.npz", {key: arrays[key] for key in ("walls", "measures", "measure_names")})
    loaded = maze_dataset.load(path)
    assert loaded.shape == (16, 16) and loaded.occupancy is None and loaded.retest is None
    np.testing.assert_array_equal(loaded.walls, data.walls)


BROKEN = {
    "missing walls": (lambda a: a.pop("walls"), "missing key 'walls'"),
    "missing measure_names": (lambda a: a.pop("measure_names"), "missing key 'measure_names'"),
    "walls not uint8": (lambda a: a.update(walls=a["walls"].astype(np.int16)), "'walls' must be uint8"),
    "walls of wrong width": (lambda a: a.update(walls=a["walls"][:, :30]), "30 bytes per level"),
    "measures float64": (lambda a: a.update(measures=a["measures"].astype(np.float64)), "'measures' must be float32"),
    "measures of another N": (lambda a: a.update(measures=a["measures"][:-1]), "4 rows but 'walls' has 5 levels"),
    "measures with NaN": (lambda a: a["measures"].__setitem__((0, 0), np.nan), "NaN or infinite"),
    "names count": (lambda a: a.update(measure_names=np.array(["mean_path_length"])), "1 names but 'measures' has 2"),
    "no path length": (lambda a: a.update(measure_names=np.array(["walls", "path"])), "must name the path length"),
    "occupancy of another N": (lambda a: a.update(occupancy=a["occupancy"][:3]), "'occupancy' must be float of shape"),
    "retest of wrong shape": (lambda a: a.update(measures_retest=a["measures"][:, :1].copy()), "'measures_retest'"),
    "iteration of another N": (lambda a: a.update(iteration=np.zeros(4, np.int64)), "'iteration' must be integers"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_file_fails_naming_the_file_and_the_problem(tmp_path, case):
    data = synthetic(5)
    data.retest = data.measures.copy()
    data.iteration = np.zeros(5, np.int64)
    arrays = data.arrays()
    change, message = BROKEN[case]
    change(arrays)
    path = write(tmp_path / "broken.npz", arrays)
    with pytest.raises(MazeDatasetError, match=re.escape(message)) as raised:
        maze_dataset.load(path)
    assert str(path) in str(raised.value)


def test_not_an_npz_and_no_file_fail_clearly(tmp_path):
    (tmp_path / "x.npz").write_text("not a zip")
    with pytest.raises(MazeDatasetError, match="not a readable .npz"):
        maze_dataset.load(tmp_path / "x.npz")
    with pytest.raises(MazeDatasetError, match="no such file"):
        maze_dataset.load(tmp_path / "missing.npz")


def test_a_run_folder_round_trips_through_the_file_into_the_benchmark_data(tmp_path):
    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.core.loop import run_locally
    from dsage_ray.domains.maze.encoding import WALL
    from dsage_ray.surrogate.dataset import _unpack

    config = RunConfig.build({"domain": "maze", "preset": "tiny", "maze.agent": "builtin:wall_follower",
                              "maze.episodes": 1, "budget": 40, "n_rand": 20, "surrogate.epochs": 1,
                              "qd.exploit_iterations": 2, "selection.count": 10, "experimental.holdout_levels": 4,
                              "image_every": 1000})
    run = run_locally(config, out_dir=tmp_path / "run", console=False)
    import torch

    threads = torch.get_num_threads()
    maze_dataset.main(["from-run", str(run), "--out", str(tmp_path / "run.npz"),
                       "--holdout-out", str(tmp_path / "held.npz"), "--retest", "5"])
    assert torch.get_num_threads() == threads  # the in-process retest pinned the run's threads, then gave them back
    data, held = maze_dataset.load(tmp_path / "run.npz"), maze_dataset.load(tmp_path / "held.npz")

    state = load_checkpoint(Path(run) / CHECKPOINT_NAME)
    stored = state["dataset"]
    levels = _unpack(stored["levels"], tuple(stored["level_shape"]))
    assert len(data) == len(stored["objective"]) == 40
    np.testing.assert_array_equal(data.walls, levels[:, WALL, :16, :16] > 0.5)
    np.testing.assert_array_equal(data.measures, stored["measures"].astype(np.float32))
    np.testing.assert_array_equal(data.occupancy, stored["occupancy"])
    assert data.measure_names == ("num_walls", "mean_path_length")
    # Each level's wall count is its num_walls measure: walls and measures stayed aligned.
    np.testing.assert_array_equal(data.walls.reshape(40, -1).sum(axis=1), data.measures[:, 0])
    # The retest evaluated 5 of the levels again, each against its own row (num_walls is the level's own).
    retested = np.isfinite(data.retest).all(axis=1)
    assert retested.sum() == 5 and np.isnan(data.retest[~retested]).all()
    np.testing.assert_array_equal(data.retest[retested, 0], data.measures[retested, 0])
    assert data.iteration[0] == 0 and data.iteration[-1] == len(state["history"]) - 1
    assert np.all(np.diff(data.iteration) >= 0)
    np.testing.assert_array_equal(held.walls.reshape(len(held), -1), np.asarray(state["holdout"]["solutions"]) > 0)


def test_the_benchmark_ends_with_one_line_per_n_in_the_required_format(tmp_path, capsys):
    import bench_surrogate_ceiling

    path = maze_dataset.save(synthetic(48), tmp_path / "d.npz")
    bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "16,24", "--test", "20", "--splits", "3",
                                  "--inits", "1", "--epochs", "1", "--batch", "8"])
    lines = capsys.readouterr().out.strip().splitlines()
    matches = [LAST_LINE.fullmatch(line) for line in lines[-2:]]
    assert all(matches), lines[-2:]
    assert [int(m.group(1)) for m in matches] == [16, 24]
    # The path length here is exactly twice the optimal path: that baseline ranks it perfectly.
    assert all(m.group(4) == "1.000" and m.group(5) == "0.000" for m in matches)
    assert not any(LAST_LINE.fullmatch(line) for line in lines[:-2])


def test_the_benchmark_refuses_data_too_small_for_the_test_set(tmp_path):
    import bench_surrogate_ceiling

    path = maze_dataset.save(synthetic(12), tmp_path / "d.npz")
    with pytest.raises(SystemExit, match="cannot hold 20 test levels"):
        bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "16", "--test", "20"])


def test_bfs_features_match_the_domain(tmp_path):
    import bench_surrogate_ceiling

    from dsage_ray.domains.maze.level import MazeLevel

    data = synthetic(6, seed=3)
    features = bench_surrogate_ceiling.bfs_features(data.walls)
    names = bench_surrogate_ceiling.FEATURE_NAMES
    for walls, row in zip(data.walls, features):
        level = MazeLevel.from_bitmap(walls)
        assert row[names.index("optimal_path")] == level.optimal_path_length
        assert row[names.index("reachable")] == level.reachable_cells.sum()
        assert (row[names.index("start_row")], row[names.index("start_col")]) == level.start


def test_concatenated_datasets_keep_each_level_once_in_order():
    first, second = synthetic(10), synthetic(6, seed=1)
    second.walls[:3] = first.walls[4:7]  # two runs of one seed share their first random levels
    merged = maze_dataset.concatenate([first, second])
    assert len(merged) == 13 and merged.iteration is None
    np.testing.assert_array_equal(merged.walls[:10], first.walls)
    np.testing.assert_array_equal(merged.measures[10:], second.measures[3:])
    with pytest.raises(MazeDatasetError, match="different measures"):
        maze_dataset.concatenate([first, MazeData(walls=second.walls, measures=second.measures[:, :1],
                                                  measure_names=("other",))])
    assert maze_dataset.concatenate([]) is None


def test_data_without_the_path_length_is_refused_and_nothing_is_written(tmp_path):
    # An audit search's measures are the level's own (walls, optimal path), not the agent's path length.
    data = synthetic(6)
    data.measure_names = ("num_walls", "optimal_path_length")
    with pytest.raises(MazeDatasetError, match="mean_path_length"):
        maze_dataset.save(data, tmp_path / "audit.npz")
    assert list(tmp_path.iterdir()) == []


def test_with_several_inits_the_ensemble_and_its_gbm_blend_are_scored(tmp_path):
    import bench_surrogate_ceiling

    path = maze_dataset.save(synthetic(48), tmp_path / "d.npz")
    result = bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "16", "--test", "20", "--splits", "2",
                                           "--inits", "2", "--epochs", "1", "--batch", "8", "--no-future"])
    for key in ("ensemble", "with_gbm", "with_walker"):
        scores = result[key]["cpu"][16]
        assert len(scores) == 2 and all(-1.0 <= r <= 1.0 for r in scores)
    assert len(result["walker"]) == 2 and all(-1.0 <= r <= 1.0 for r in result["walker"])
    parts = result["disagreement"]["cpu"][16]
    assert len(parts) == 2
    for d in parts:
        assert np.isfinite([d.spread_rho, d.value_rho, d.within_rho, d.mae, d.certain_mae]).all()
        assert -1.0 <= d.within_rho <= 1.0 and 0.0 <= d.certain_mae


def test_disagreement_scores_the_spread_against_the_error_of_the_mean():
    from bench_surrogate_ceiling import Disagreement

    rng = np.random.default_rng(0)
    truth = np.linspace(0.0, 600.0, 200)
    spread = rng.uniform(1.0, 50.0, 200)
    # Two members at mean ± spread: the mean is off by exactly the spread, so the spread ranks the error perfectly.
    offset = spread * np.where(rng.random(200) < 0.5, -1.0, 1.0)
    predictions = np.stack([truth + offset - spread, truth + offset + spread])
    result = Disagreement.of(predictions, truth, fraction=0.25)
    assert result.spread_rho == pytest.approx(1.0)
    assert result.within_rho == pytest.approx(1.0)
    assert result.mae == pytest.approx(spread.mean())
    assert result.certain_mae == pytest.approx(np.sort(spread)[:50].mean())


def test_a_spread_that_only_follows_the_prediction_has_no_information_within_its_deciles():
    from bench_surrogate_ceiling import Disagreement

    rng = np.random.default_rng(1)
    long = rng.random(1000) < 0.5
    truth = np.where(long, 500.0, 100.0) + rng.uniform(-20.0, 20.0, 1000)
    error = np.abs(rng.normal(0.0, np.where(long, 50.0, 5.0)))  # long paths are harder
    mean = truth + error * np.where(rng.random(1000) < 0.5, -1.0, 1.0)
    spread = np.where(mean > 300.0, 10.0, 1.0) + rng.uniform(0.0, 0.1, 1000)  # says "long path", nothing else
    result = Disagreement.of(np.stack([mean - spread, mean + spread]), truth, fraction=0.5)
    assert result.spread_rho > 0.5 and result.value_rho > 0.5
    assert abs(result.within_rho) < 0.1


def test_the_random_walk_baseline_is_the_walkers_hitting_time_and_a_setting_can_read_its_visits(tmp_path):
    import bench_surrogate_ceiling

    data = synthetic(30, seed=5)
    hitting = bench_surrogate_ceiling.hitting_times(data.walls, chunk=7)  # chunks must not change the answer
    np.testing.assert_allclose(hitting, bench_surrogate_ceiling.hitting_times(data.walls))
    optimal = bench_surrogate_ceiling.bfs_features(data.walls)[:, bench_surrogate_ceiling.FEATURE_NAMES.index(
        "optimal_path")]
    # A walker needs at least the shortest path, and exactly it only in a corridor without side cells.
    assert np.all(hitting >= optimal - 1e-9) and np.all(hitting > 0)
    path = maze_dataset.save(data, tmp_path / "d.npz")
    result = bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "8", "--test", "20", "--splits", "1",
                                           "--inits", "1", "--epochs", "1", "--batch", "8", "--no-future",
                                           "--setting", "walk:bench.random_walk=true"])
    assert -1.0 <= result["rho"]["walk"][8][0] <= 1.0


def test_the_networks_level_statistics_are_the_gbms_features():
    # grid_features.LevelStatistics (torch, fed to a network's heads) must compute what the GBM reads (numpy), in its units.
    import bench_surrogate_ceiling
    import torch

    from dsage_ray.domains.maze.encoding import EMPTY, GOAL, SPARE, START, encode_levels
    from dsage_ray.surrogate.grid_features import DistanceFields, LevelStatistics
    from dsage_ray.surrogate.models import pad_to_power_of_two

    walls = np.stack([level.walls for level in random_valid_levels(10, seed=4, height=10, width=12,
                                                                  density_range=(0.0, 0.7))])
    encoded = pad_to_power_of_two(encode_levels(walls.reshape(10, -1).astype(np.int8), 10, 12), SPARE)
    fields = DistanceFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=60)
    statistics = LevelStatistics(fields=fields, norm=60)(torch.from_numpy(encoded)).numpy().astype(np.float64)
    expected = bench_surrogate_ceiling.bfs_features(walls)
    area, size = 16 * 16, 16
    units = {"optimal_path": 60, "reachable": area, "on_shortest_paths": area, "dead_ends": area, "junctions": area,
             "shortest_path_junctions": area, "mean_from_start": 60, "max_from_start": 60, "mean_detour": 60,
             "max_detour": 60, "detour<=2": area, "detour<=6": area, "detour<=12": area, "manhattan": 2 * size,
             "path/manhattan": 4}
    for name, unit in units.items():
        np.testing.assert_allclose(statistics[:, LevelStatistics.names.index(name)] * unit,
                                   expected[:, bench_surrogate_ceiling.FEATURE_NAMES.index(name)], rtol=1e-5,
                                   atol=1e-4, err_msg=name)
    # "walls" counts every cell an agent cannot stand on, the padding included.
    np.testing.assert_allclose(statistics[:, LevelStatistics.names.index("walls")] * area - (area - 120),
                               expected[:, bench_surrogate_ceiling.FEATURE_NAMES.index("walls")], atol=1e-3)


def test_a_level_statistics_setting_trains_and_is_described(tmp_path):
    import bench_surrogate_ceiling

    path = maze_dataset.save(synthetic(48), tmp_path / "d.npz")
    result = bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "16", "--test", "20", "--splits", "1",
                                           "--inits", "1", "--epochs", "1", "--batch", "8", "--no-future",
                                           "--setting", "hybrid:occupancy_sum_measure=,bench.level_statistics=true",
                                           "--setting", "residual:bench.level_statistics=true,bench.sum_residual=true"])
    for name in ("hybrid", "residual"):
        assert -1.0 <= result["rho"][name][16][0] <= 1.0


def test_the_in_process_evaluator_pins_the_runs_torch_threads():
    # Torch's default (one thread per core) made the in-process retest several times slower beside other jobs.
    from dsage_ray.config import RunConfig

    config = RunConfig.build({"domain": "maze", "preset": "tiny", "maze.agent": "builtin:wall_follower"})
    with maze_dataset.Evaluator(config, workers=0) as evaluator:
        assert evaluator.evaluator.threads == config.torch_threads == 1


def test_a_run_without_the_path_length_is_refused_naming_the_run_before_any_retest(tmp_path):
    from dsage_ray.config import RunConfig
    from dsage_ray.core.loop import run_locally

    config = RunConfig.build({"domain": "maze", "preset": "tiny", "maze.agent": "builtin:wall_follower",
                              "maze.episodes": 1, "budget": 20, "n_rand": 20, "surrogate.epochs": 1,
                              "maze.measures": ["num_walls", "optimal_path_length"], "image_every": 1000})
    run = run_locally(config, out_dir=tmp_path / "audit_like", console=False)
    with pytest.raises(SystemExit, match=r"audit_like: its measures \['num_walls', 'optimal_path_length'\]"):
        maze_dataset.main(["from-run", str(run), "--out", str(tmp_path / "out.npz"), "--retest", "5"])
    assert not (tmp_path / "out.npz").exists()


def test_a_rotations_setting_trains_on_each_level_turned_with_its_occupancy(tmp_path, monkeypatch):
    import bench_surrogate_ceiling as bench

    data = synthetic(24)
    setting = bench.Setting.parse("rot:bench.rotations=true", epochs=1, extra={})
    model = bench.Model(setting, data, train_size=8, seed=0)
    seen = []
    monkeypatch.setattr(model.surrogate, "train", lambda dataset: seen.append(dataset))
    encoded = model.encode(data.walls)
    model.train(np.arange(8), encoded)
    stored = seen[0]
    assert len(stored) == 4 * 8
    np.testing.assert_array_equal(stored.levels(slice(8, 16)), np.rot90(encoded[:8], 1, axes=(2, 3)))
    np.testing.assert_array_equal(stored.occupancy[24:], np.rot90(data.occupancy[:8], 3, axes=(1, 2)))
    np.testing.assert_array_equal(stored.measures[16:24], data.measures[:8])
    assert bench.Setting.parse("t:bench.rotations=tta", epochs=1, extra={}).rotations == "tta"
    with pytest.raises(SystemExit, match="bench.rotations is true, false or tta"):
        bench.Setting.parse("x:bench.rotations=twice", epochs=1, extra={})
    result = bench.main(["--data", str(maze_dataset.save(data, tmp_path / "d.npz")), "--sizes", "8", "--test", "12",
                         "--splits", "1", "--inits", "1", "--epochs", "1", "--batch", "8", "--no-future",
                         "--setting", "tta:bench.rotations=tta"])
    assert -1.0 <= result["rho"]["tta"][8][0] <= 1.0


def test_a_policy_chain_setting_is_scored_and_blended_with_the_first_setting(tmp_path, capsys):
    import bench_surrogate_ceiling

    path = maze_dataset.save(synthetic(30, seed=3), tmp_path / "d.npz")
    result = bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "8", "--test", "20", "--splits", "2",
                                           "--inits", "1", "--epochs", "1", "--batch", "4", "--no-future",
                                           "--setting", "net:channels=8", "--setting", "chain:bench.chain=2"])
    out = capsys.readouterr().out
    assert "setting chain: policy chain (benchmarks/policy_chain.py), 2 memory mode(s)" in out
    assert "net + chain ranks" in out
    assert len(result["rho"]["chain"][8]) == 2 and all(-1.0 <= r <= 1.0 for r in result["rho"]["chain"][8])
    assert len(result["pairs"]["chain"][8]) == 2
    flops, _, full_rate = result["cost"]["chain"]
    assert flops > result["cost"]["net"][0] and full_rate > 0


@pytest.mark.parametrize("value", ["-1", "yes", "1.5"])
def test_a_bad_chain_setting_is_refused_by_name(value):
    import bench_surrogate_ceiling

    with pytest.raises(SystemExit, match="bench.chain is a number of memory modes"):
        bench_surrogate_ceiling.Setting.parse(f"c:bench.chain={value}", epochs=1, extra={})


def test_a_chain_needs_the_agents_occupancy(tmp_path):
    import bench_surrogate_ceiling

    data = synthetic(30)
    data.occupancy = None
    path = maze_dataset.save(data, tmp_path / "d.npz")
    with pytest.raises(SystemExit, match="bench.chain trains on the agent's occupancy"):
        bench_surrogate_ceiling.main(["--data", str(path), "--sizes", "8", "--test", "20", "--splits", "1",
                                      "--inits", "1", "--epochs", "1", "--no-future", "--setting", "c:bench.chain=1"])


def test_a_chain_refuses_to_predict_a_measure_other_than_the_path_length():
    import bench_surrogate_ceiling

    data = synthetic(8)
    setting = bench_surrogate_ceiling.Setting.parse("c:bench.chain=1", epochs=1, extra={})
    model = bench_surrogate_ceiling.make_model(setting, data, train_size=4, seed=0)
    walls = model.encode(data.walls[:2])
    assert model.predict(walls, data.measure("mean_path_length")).shape == (2,)
    with pytest.raises(ValueError, match="predicts mean_path_length only, not num_walls"):
        model.predict(walls, data.measure("num_walls"))
