"""One error type and one handler: every command ends bad input, resource problems and failed
trials with one line ``dsage-ray <command>: error: ...`` and the exit code of the error's kind."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from dsage_ray.cli import main
from dsage_ray.errors import DsageError, InputError, ResourceError, TrialFailed, describe

ROOT = Path(__file__).resolve().parents[1]
CONFIG = str(ROOT / "experiments" / "configs" / "maze_dsage.toml")


def dsage_ray(*argv: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """``dsage-ray ARGV`` in a fresh process, as a user runs it."""
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    env.pop("RAY_ADDRESS", None)  # a local cluster: the case the pre-start check covers
    # `make test` preloads the JDK's libjsig for Mario, which warns on stderr in any process that sets a
    # signal handler; these commands never start a JVM, and the user's shell has no such preload.
    env.pop("LD_PRELOAD", None)
    return subprocess.run([sys.executable, "-m", "dsage_ray.cli", *argv], cwd=ROOT, env=env, text=True,
                          capture_output=True, timeout=timeout)


def test_too_many_workers_is_one_line_before_ray_starts(tmp_path):
    proc = dsage_ray("run", CONFIG, "--preset", "tiny", "--workers", "64", "--out", str(tmp_path / "out"))
    assert proc.returncode == ResourceError.exit_code == 3, proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr  # nothing from Ray: it never started
    assert proc.stderr.startswith("dsage-ray run: error: one trial (ray.trial_cpus=") and \
        "ray.num_workers=64" in proc.stderr
    assert proc.stdout == "" and not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv, message", [
    (["run", CONFIG, "--set", "surrogate.epoch=5"], "dsage-ray run: error: surrogate.epoch: unknown config key"),
    (["run", "no/such/config.toml", "--local"], "dsage-ray run: error: "),
    (["ablate", CONFIG, "--set", "budget=-1"], "dsage-ray ablate: error: budget"),
    (["config", CONFIG, "--set", "budget"], "dsage-ray config: error: "),
])
def test_bad_input_is_one_line_with_exit_code_2(argv, message, capsys):
    assert main(argv) == InputError.exit_code == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(message) and captured.err.count("\n") == 1, captured.err
    assert captured.out == ""


def test_unknown_config_file_names_the_file(capsys):
    assert main(["config", "no/such/config.toml"]) == 2
    assert "no/such/config.toml" in capsys.readouterr().err


def test_every_package_error_has_a_kind_and_its_exit_code():
    from dsage_ray.agents.base import AgentError
    from dsage_ray.config import ConfigError
    from dsage_ray.core.checkpoint import CheckpointError
    from dsage_ray.domains.mario.generator import GeneratorError
    from dsage_ray.domains.mario.human_levels import MarioDataError
    from dsage_ray.domains.mario.simulator import SimulatorError
    from dsage_ray.domains.mario.tiles import LevelError
    from dsage_ray.domains.maze.layout import LayoutError
    from dsage_ray.ray.experiment import ExperimentInterrupted
    from dsage_ray.ray.pool import PoolResourceError

    codes = {error: describe(error("x"))[0] for error in (
        ConfigError, AgentError, LayoutError, LevelError, CheckpointError, GeneratorError,
        PoolResourceError, SimulatorError, MarioDataError, ExperimentInterrupted)}
    assert codes == {ConfigError: 2, AgentError: 2, LayoutError: 2, LevelError: 2, CheckpointError: 2,
                     GeneratorError: 2, PoolResourceError: 3, SimulatorError: 3, MarioDataError: 3,
                     ExperimentInterrupted: 5}
    assert all(issubclass(error, DsageError) for error in codes)
    # The names callers catch today still work.
    assert issubclass(ConfigError, ValueError) and issubclass(GeneratorError, RuntimeError)
    assert issubclass(PoolResourceError, RuntimeError)


def test_describe_builtin_failures():
    assert describe(FileNotFoundError(2, "No such file or directory", "a.toml")) == (
        2, "a.toml: No such file or directory")
    assert describe(KeyboardInterrupt()) == (130, "interrupted")
    assert describe(RuntimeError("actor died\n  twice")) == (1, "actor died twice")


def broken_domain(config):
    """A domain factory that fails inside the trial (the driver never builds the domain)."""
    raise ValueError("the level generator is missing")


@pytest.mark.parametrize("api", ["tuner", "run"])
def test_a_failed_trial_is_one_line_with_its_error_and_log(api, ray_session, tmp_path):
    """A real Tune trial that raises: both Tune APIs end in TrialFailed naming the error and error.txt."""
    from dsage_ray.ray.experiment import run_experiment
    from tests.ray.helpers import small_config

    with pytest.raises(TrialFailed) as failure:
        run_experiment(small_config().to_flat(), name=f"broken_{api}", storage_path=tmp_path, api=api,
                       max_failures=0, domain_factory=broken_domain)
    error = failure.value
    assert error.error_file is not None and error.error_file.name == "error.txt" and error.error_file.is_file()
    assert error.error_file.is_relative_to(tmp_path / f"broken_{api}")
    assert "the level generator is missing" in error.error_file.read_text()  # Tune's full traceback
    code, line = describe(error)
    assert code == TrialFailed.exit_code == 4
    assert line == f"the trial failed: ValueError: the level generator is missing (log: {error.error_file})"
