"""MarioDomain behind the Domain protocol, and the ``mario`` CLI commands."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.domains.mario.domain import MarioDomain
from dsage_ray.domains.mario.plugin import MarioConfig
from dsage_ray.types import AuditableDomain, Domain

from .conftest import needs_java, needs_javac


def small_config(**overrides) -> MarioConfig:
    values = dict(runs=2, timer=4, astar_iterations=100, episode_timeout_s=60.0)
    values.update(overrides)
    return MarioConfig(**values)


def test_domain_protocol_and_shapes(rng):
    domain = MarioDomain(config=small_config())
    assert isinstance(domain, Domain) and isinstance(domain, AuditableDomain)
    assert domain.solution_dim == 32 and domain.occupancy_shape == (16, 56) and domain.encoding_channels == 17
    assert domain.archive_dims == (150, 100) and domain.measure_ranges == ((0.0, 150.0), (0.0, 100.0))
    z = domain.random_solutions(5, rng)
    assert z.shape == (5, 32) and abs(z.mean()) < 0.5
    x = domain.encode(z)
    assert x.shape == (5, 17, 64, 64) and x.dtype == np.float32
    assert (x[:, :, :16, :56].argmax(1) == domain.levels(z)).all()
    clone = pickle.loads(pickle.dumps(domain))
    assert clone._generator is None and (clone.level(z[0]) == domain.level(z[0])).all()
    assert domain.render(z[0], None).startswith(b"\x89PNG")


def test_build_domain_and_unknown_measures():
    from dsage_ray.domains import build_domain

    domain = build_domain(RunConfig.build({"domain": "mario", "preset": "tiny"}))
    assert isinstance(domain, MarioDomain) and domain.config.runs == 1
    with pytest.raises(ValueError, match="unknown measure"):
        MarioDomain(config=small_config(measures=("sky_tiles", "speed"), archive_dims=(10, 10)))
    kills = MarioDomain(config=small_config(measures=("sky_tiles", "enemies_killed"), archive_dims=(150, 25),
                                            measure_ranges=()))
    assert kills.measure_ranges == ((0.0, 150.0), (0.0, 25.0))


@needs_java
@needs_javac
def test_evaluate_end_to_end(rng):
    domain = MarioDomain(config=small_config())
    z = domain.random_solutions(1, rng)[0]
    result = domain.evaluate(z, seed=0)
    assert not result.failed, result.error
    level = domain.level(z)
    assert result.info["level"] == "\n".join("".join("-*ygkrtS!@FX%M|o#"[t] for t in row) for row in level)
    assert result.measures.shape == (2,) and result.measures[0] == np.count_nonzero(level[:9])
    assert result.measures[1] == np.mean(result.info["jumps"])
    assert result.objective == pytest.approx(np.mean(result.info["completion"]))
    assert result.occupancy.shape == (16, 56) and result.occupancy.dtype == np.float32
    assert result.occupancy.sum() <= max(result.info["ticks"])
    assert len(result.info["completion"]) == 2 and result.info["episodes_played"] == 1  # deterministic
    assert result.info["status"][0] in ("WIN", "LOSE", "TIME_OUT")
    json.dumps(result.info)
    again = domain.evaluate(z, seed=1)
    assert again.objective == result.objective and (again.occupancy == result.occupancy).all()
    # Its work, per run: the ticks played and the A* iterations spent on them (as repeatable as the rest).
    work = domain.work_counts(result)
    assert set(work) == set(domain.work_names) == {"search_iterations", "ticks"} and work == domain.work_counts(again)
    assert work["ticks"] == result.info["ticks"][0] <= work["search_iterations"] <= 100 * work["ticks"]


@needs_java
def test_failed_evaluation_carries_the_error(rng):
    domain = MarioDomain(config=small_config(episode_timeout_s=1e-4, astar_iterations=1000, timer=20))
    result = domain.evaluate(domain.random_solutions(1, rng)[0], seed=0)
    if not result.failed and result.info["ticks"][0] == 0:
        pytest.skip("this latent's level ends before the first tick, so no timeout can happen")
    assert result.failed and "WALL_CLOCK_TIMEOUT" in result.error
    assert result.objective == 0.0 and result.occupancy.shape == (16, 56)


# ------------------------------------------------------------------------------------------ CLI

def run_cli(argv: list[str]) -> int:
    from dsage_ray.cli import main

    return main(argv)


@needs_java
@needs_javac
def test_cli_eval_json(tmp_level_file, tmp_path, capsys):
    png = tmp_path / "out.png"
    assert run_cli(["mario", "eval", "--level", str(tmp_level_file), "--runs", "3", "--json",
                    "--render", str(png)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["status"] == ["WIN"] * 3 and data["objective"] == 1.0 and data["runs"] == 3
    assert png.read_bytes().startswith(b"\x89PNG")


def test_cli_eval_bad_level_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.txt"
    bad.write_text("\n".join(["--"] * 15 + ["-?"]) + "\n")
    assert run_cli(["mario", "eval", "--level", str(bad)]) == 2
    message = capsys.readouterr().err
    assert message.startswith("dsage-ray mario eval: error:") and "'?'" in message and message.count("\n") == 1
    assert run_cli(["mario", "eval", "--level", str(tmp_path / "nope.txt")]) == 2
    assert "cannot read level file" in capsys.readouterr().err


def test_cli_sample_writes_text_and_png(tmp_path, capsys):
    out = tmp_path / "samples"
    assert run_cli(["mario", "sample", "--n", "3", "--out", str(out)]) == 0
    texts = sorted(out.glob("level_*.txt"))
    assert len(texts) == 3 and len(list(out.glob("level_*.png"))) == 3
    from dsage_ray.domains.mario.tiles import load_level

    assert load_level(texts[0]).shape == (16, 56)
    assert np.load(out / "latents.npy").shape == (3, 32)
    capsys.readouterr()
    assert run_cli(["mario", "sample", "--n", "2", "--out", str(out), "--generator", str(tmp_path / "none.pt")]) == 2
    assert "generator weights not found" in capsys.readouterr().err


def test_the_nominal_level_is_flat_ground():
    from dsage_ray.domains.mario.domain import flat_level
    from dsage_ray.domains.mario.tiles import to_string

    rows = to_string(flat_level()).splitlines()
    assert rows[:14] == ["-" * 56] * 14 and rows[14:] == ["X" * 56] * 2


@needs_java
@needs_javac
def test_astar_crosses_the_flat_level_unless_its_timer_is_too_short():
    from dsage_ray.types import NominalDomain

    domain = MarioDomain(config=MarioConfig(runs=3, timer=5, astar_iterations=400))
    assert isinstance(domain, NominalDomain)
    played = domain.play_nominal(seed=0)
    # The iteration-count timer makes the three runs one episode.
    assert (played.mean_return, played.success_rate, played.episodes) == (1.0, 1.0, 1)
    short = MarioDomain(config=MarioConfig(runs=1, timer=1, astar_iterations=400)).play_nominal(seed=0)
    assert short.success_rate == 0.0 and 0.0 < short.mean_return < 1.0 and "mario.timer = 1 s" in short.causes
