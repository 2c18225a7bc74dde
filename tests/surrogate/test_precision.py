"""``surrogate.precision``: which arithmetic ``auto`` picks, and what bf16 does to a trained Maze surrogate."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dsage_ray.config import SurrogateConfig
from dsage_ray.domains.maze.domain import MazeDomain
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.plugin import MazeConfig
from dsage_ray.qd.archives import make_archive
from dsage_ray.surrogate import Surrogate
from dsage_ray.surrogate import surrogate as surrogate_module
from dsage_ray.surrogate.models import pad_to_power_of_two
from dsage_ray.surrogate.surrogate import resolve_precision
from tests.surrogate.helpers import random_levels, toy_results

OCC = (6, 7)


def make(kind="two_stage", **config):
    config = SurrogateConfig(**{"epochs": 1, "batch_size": 16, "device": "cpu", **config})
    return Surrogate(kind=kind, input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                     config=config, seed=0)


@pytest.fixture
def native_bf16(monkeypatch):
    """Sets what the CPU detector answers."""
    def set_answer(answer: bool) -> None:
        monkeypatch.setattr(surrogate_module, "native_cpu_bf16", lambda: answer)
    return set_answer


def test_auto_is_bf16_only_with_native_support_and_explicit_choices_stand(native_bf16):
    cpu = torch.device("cpu")
    native_bf16(False)
    assert resolve_precision("auto", cpu) == "fp32" and make(precision="auto").precision == "fp32"
    assert resolve_precision("bf16", cpu) == "bf16"  # asked for: emulated, slow, but honoured
    native_bf16(True)
    assert resolve_precision("auto", cpu) == "bf16" and make(precision="auto").precision == "bf16"
    assert resolve_precision("fp32", cpu) == "fp32" and make(precision="fp32").precision == "fp32"
    with pytest.raises(ValueError, match="precision"):
        resolve_precision("fp16", cpu)


def test_auto_without_native_bf16_predicts_exactly_as_fp32(native_bf16):
    native_bf16(False)
    levels = random_levels(12, size=8)
    auto, fp32, bf16 = (make(precision=p).predict(levels) for p in ("auto", "fp32", "bf16"))
    for field in ("objective", "measures", "occupancy"):
        assert np.array_equal(getattr(auto, field), getattr(fp32, field))
        assert getattr(bf16, field).dtype == np.float32
    # The bf16 path really is another arithmetic (else the agreement checks would prove nothing)...
    assert not np.array_equal(bf16.measures, fp32.measures)
    # ...on the same weights, within a percent of fp32's numbers (measured here: 0.03-0.3%); how far that moves a
    # trained Maze surrogate's levels between cells is the slow test below.
    for field in ("objective", "measures", "occupancy"):
        exact = getattr(fp32, field)
        assert np.abs(getattr(bf16, field) - exact).mean() < 0.01 * np.abs(exact).mean(), field


def test_the_cpu_detector_reads_the_cpu_flags(monkeypatch):
    surrogate_module.native_cpu_bf16.cache_clear()
    monkeypatch.setattr(torch.cpu, "get_capabilities", lambda: {"avx512_bf16": False, "amx_bf16": True})
    assert surrogate_module.native_cpu_bf16() is True
    surrogate_module.native_cpu_bf16.cache_clear()
    monkeypatch.setattr(torch.cpu, "get_capabilities", lambda: {"avx512_f": True, "avx2": True})
    assert surrogate_module.native_cpu_bf16() is False
    # Older torch has no get_capabilities: the kernel's flags decide.
    monkeypatch.delattr(torch.cpu, "get_capabilities")
    for flags, expected in (("fpu avx512f avx512_bf16 avx512_vnni", True), ("fpu avx2 avx512f", False)):
        surrogate_module.native_cpu_bf16.cache_clear()
        monkeypatch.setattr(surrogate_module, "Path", lambda _: _Text(f"processor\t: 0\nflags\t\t: {flags}\n"))
        assert surrogate_module.native_cpu_bf16() is expected
    surrogate_module.native_cpu_bf16.cache_clear()


class _Text:
    def __init__(self, text: str) -> None:
        self.text = text

    def read_text(self) -> str:
        return self.text


@pytest.mark.parametrize("kind", ["two_stage", "one_stage"])
def test_training_is_float32_and_unchanged_by_precision(kind):
    levels = random_levels(24, size=8)
    losses = []
    for precision in ("fp32", "bf16"):
        surrogate = make(kind, precision=precision)
        dataset = surrogate.make_dataset()
        dataset.append(encoded=levels, results=toy_results(levels, OCC))
        losses.append(surrogate.train(dataset))
        assert all(p.dtype == torch.float32 for p in surrogate.model.parameters())
    assert losses[0] == losses[1]


# bf16 within 1% of fp32: test_auto_without_native_bf16_predicts_exactly_as_fp32; its predict: test_surrogate.py's
# bf16 cases
@pytest.mark.slow
def test_bf16_keeps_a_trained_maze_surrogate_in_the_same_cells():
    """A surrogate trained on real Maze evaluations, on the Maze archive (256x162 cells over 0-256 walls and
    0-648 steps): bf16 moves few levels, never by more than one cell, and far less than the model's own error.

    The Maze's cells are one wall wide, and bf16 keeps about three significant digits inside the residual
    blocks, so a level predicted within a few hundredths of a wall of a cell edge can cross it: measured
    95-97.5% of levels stay (three seeds, and the benchmark's ACCEL-trained surrogate), not 99%.
    """
    domain = MazeDomain(config=MazeConfig(agent="builtin:wall_follower", episodes=1))
    levels = random_valid_levels(700, seed=0, density_range=(0.0, 0.9))
    solutions = np.stack([level.walls.reshape(-1) for level in levels]).astype(domain.solution_dtype)
    encoded = pad_to_power_of_two(domain.encode(solutions), domain.encoding_pad_channel)
    fit, held_out = slice(0, 400), slice(400, None)
    results = [domain.evaluate(solution, seed=0) for solution in solutions]
    surrogate = Surrogate(kind="two_stage", input_channels=domain.encoding_channels, input_shape=encoded.shape[2:],
                          occupancy_shape=domain.occupancy_shape, num_measures=2,
                          config=SurrogateConfig(device="cpu", epochs=12, batch_size=32, lr=3e-3, precision="fp32"),
                          seed=0)
    dataset = surrogate.make_dataset()
    dataset.append(encoded=encoded[fit], results=results[fit])
    surrogate.train(dataset)
    error = surrogate.mae(encoded[held_out], results[held_out])
    measures = np.array([r.measures for r in results])
    guess_the_mean = np.abs(measures[held_out] - measures[fit].mean(axis=0)).mean(axis=0)
    assert error["measure_0"] < 0.5 * guess_the_mean[0], "the surrogate learned the wall count"

    fp32 = surrogate.predict(encoded[held_out])
    surrogate.precision = "bf16"  # the same weights, only the arithmetic changes
    bf16 = surrogate.predict(encoded[held_out])
    assert bf16.measures.dtype == np.float32

    archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges)
    cells_fp32, cells_bf16 = (archive.int_to_grid_index(archive.index_of(p.measures)) for p in (fp32, bf16))
    assert np.mean((cells_fp32 == cells_bf16).all(axis=1)) >= 0.95
    assert np.abs(cells_fp32 - cells_bf16).max() <= 1
    deviation = np.abs(bf16.measures - fp32.measures).mean(axis=0)
    assert all(deviation[i] < 0.01 * error[f"measure_{i}"] for i in range(2)), (deviation, error)
