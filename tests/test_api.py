"""The public API (``from dsage_ray import ...``): what it returns, what it refuses, what it imports."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import dsage_ray
from dsage_ray.cli import main
from dsage_ray.core.tensorboard_log import tensorboard_hint
from tests.ray.helpers import tensorboard_scalars, tensorboard_tags

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "experiments" / "configs" / "maze_dsage.toml"
#: A run of two outer iterations on the deterministic stand-in agent.
SMALL = {"maze.agent": "builtin:wall_follower", "budget": 60, "maze.episodes": 2}


def test_importing_the_package_loads_no_torch_no_ray_and_gives_a_version():
    code = ("import sys, dsage_ray; print(dsage_ray.__version__); "
            "print(any(m in sys.modules for m in ('torch', 'ray', 'dsage_ray.api')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == [dsage_ray.__version__, "False"]
    assert set(dsage_ray.__all__) <= set(dir(dsage_ray))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        dsage_ray.nope  # noqa: B018


def test_the_version_flag_prints_the_installed_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == f"dsage-ray {dsage_ray.__version__}"


def test_resolve_config_reads_files_dicts_and_configs_like_the_command_line():
    from_file = dsage_ray.resolve_config(CONFIG, preset="tiny", overrides={"budget": 70})
    assert from_file.preset == "tiny" and from_file.budget == 70 and from_file.name == "maze_dsage"
    from_dict = dsage_ray.resolve_config({"surrogate.epochs": 3, "maze": {"episodes": 7}}, preset="tiny")
    assert from_dict.surrogate.epochs == 3 and from_dict.maze.episodes == 7 and from_dict.preset == "tiny"
    assert dsage_ray.resolve_config(from_file, overrides={"seed": 4}).seed == 4
    with pytest.raises(dsage_ray.InputError, match="has its preset applied already"):
        dsage_ray.resolve_config(from_file, preset="cpu")
    with pytest.raises(dsage_ray.InputError, match="expected a file path, a RunConfig or a dict"):
        dsage_ray.resolve_config(42)
    with pytest.raises(ValueError, match="surogate"):  # ConfigError names the unknown key
        dsage_ray.resolve_config({"surogate.epochs": 3})


#: The command line of the local run of :data:`SMALL` (``--out`` to add).
SMALL_RUN_ARGS = ["run", str(CONFIG), "--preset", "tiny", *(f"--set={key}={value}" for key, value in SMALL.items()),
                  "--local"]


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory) -> Path:
    """The folder of :data:`SMALL_RUN_ARGS`'s run, for the tests that read it (a test that changes it copies it).

    What the command printed is beside it, in ``stdout.txt``.
    """
    out = tmp_path_factory.mktemp("cli") / "run"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main([*SMALL_RUN_ARGS, "--out", str(out)]) == 0
    (out.parent / "stdout.txt").write_text(printed.getvalue())
    return out


def test_a_local_run_prints_its_progress_and_points_at_its_folder_and_tensorboard(cli_run):
    stdout = (cli_run.parent / "stdout.txt").read_text()
    *_, folder_line, tensorboard_line = stdout.rstrip().splitlines()
    assert folder_line == f"run folder: {cli_run}"
    assert tensorboard_line == f"open it in TensorBoard: {tensorboard_hint(cli_run)}"
    history = json.loads((cli_run / "metrics.json").read_text())
    ours = tensorboard_scalars(cli_run, prefix="dsage/")
    assert [step for step, _ in ours["dsage/outer_iteration"]] == [int(m["evals"]) for m in history]
    # The archive's numbers also within each iteration (qd.growth.growth_curve).
    assert {int(m["evals"]) for m in history} < {step for step, _ in ours["dsage/coverage"]}
    _, images = tensorboard_tags(cli_run)
    assert "archive/heatmap" in images
    progress = [line for line in stdout.splitlines() if line.startswith("iter ")]
    assert len(progress) == len(history) and progress[-1].endswith("ETA done")


def test_run_returns_its_folder_metrics_archive_and_checkpoint_as_the_cli_writes_them(tmp_path, cli_run):
    result = dsage_ray.run(CONFIG, preset="tiny", overrides=SMALL, local=True, out=tmp_path / "api")
    assert isinstance(result, dsage_ray.RunResult) and result.path == tmp_path / "api"
    assert result.checkpoint.is_file() and result.metrics[-1]["evals"] == 60
    assert result.metrics == json.loads((result.path / "metrics.json").read_text())
    # The same run from the command line: same metrics (but the timings) and the same archive.
    cli = json.loads((cli_run / "metrics.json").read_text())
    untimed = lambda rows: [{k: v for k, v in row.items() if "time" not in k} for row in rows]  # noqa: E731
    assert untimed(cli) == untimed(result.metrics)
    assert (cli_run / "archive.csv").read_text() == (result.path / "archive.csv").read_text()
    assert len(result.archive) == len(result.archive.data()["index"]) > 0


def test_a_run_whose_agent_does_not_load_fails_before_anything_starts(tmp_path, capsys):
    with pytest.raises(dsage_ray.InputError, match="agent 'dcd:/missing/agent.tar'"):
        dsage_ray.run(CONFIG, preset="tiny", overrides={"maze.agent": "dcd:/missing/agent.tar"}, local=True,
                      out=tmp_path / "run")
    assert not (tmp_path / "run").exists()  # nothing half-written
    # The command line says the same in one line, for a run through Tune too (no cluster is started).
    assert main(["run", str(CONFIG), "--preset", "tiny", "--set", "maze.agent=dcd:/missing/agent.tar",
                 "--out", str(tmp_path / "tune")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dsage-ray run: error: agent 'dcd:/missing/agent.tar'") and err.count("\n") == 1, err
    assert not (tmp_path / "tune").exists()


def test_run_audit_refuses_bad_arguments_before_searching(tmp_path):
    with pytest.raises(dsage_ray.InputError, match="budget must be positive"):
        dsage_ray.run_audit(agent="builtin:random", budget=0, local=True, out=tmp_path / "a")
    with pytest.raises(dsage_ray.InputError, match="collect_only needs the out folder"):
        dsage_ray.run_audit(agent="builtin:random", collect_only=True)
    assert not (tmp_path / "a").exists()


# 37 s: run_audit and Collection through the CLI's audits (tests/audit/test_audit.py), run() in
# test_run_returns_its_folder_metrics_archive_and_checkpoint_as_the_cli_writes_them; this runs the example script.
@pytest.mark.slow
def test_the_api_example_runs_and_returns_levels_with_seeds_and_a_report(tmp_path):
    """``examples/api_quickstart.py``, as a user runs it from the project root."""
    proc = subprocess.run([sys.executable, "examples/api_quickstart.py", str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600,
                          env={"PATH": "/usr/bin:/bin", "RAY_AUTH_MODE": "disabled", "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    collection = dsage_ray.Collection.load(tmp_path / "audit" / "collection")
    assert collection.report_path.is_file() and collection.agent == "builtin:random" and collection.levels
    stored = json.loads((collection.path / "collection.json").read_text())["levels"]
    assert [(level.seed, level.success_rate) for level in collection.levels] == [
        (entry["seed"], entry["success_rate"]) for entry in stored]
    assert all(level.level_path.is_file() and level.image_path.is_file() for level in collection.levels)
    assert f"report: {collection.report_path}" in proc.stdout
    assert f"level #{collection.levels[0].id}: success {collection.levels[0].success_rate:.2f}" in proc.stdout
    assert "run: 60 evaluations, QD-score" in proc.stdout and (tmp_path / "run" / "checkpoint.dsage").is_file()


def test_a_run_resumes_as_it_began_when_a_default_changed_since(tmp_path, cli_run, monkeypatch, capsys):
    import dsage_ray.config.layering as config_module  # the presets RunConfig.build layers

    out = tmp_path / "run"
    shutil.copytree(cli_run, out)  # a run of these arguments, as this test's own
    args = [*SMALL_RUN_ARGS, "--out", str(out)]
    began = json.loads((out / "config.json").read_text())["qd"]["exploit_iterations"]
    # As if a later version changed the tiny preset's inner loop.
    presets = config_module.presets
    monkeypatch.setattr(config_module, "presets", lambda domain: {
        name: {**values, "qd.exploit_iterations": began + 1} for name, values in presets(domain).items()})
    assert dsage_ray.resolve_config(CONFIG, preset="tiny").qd.exploit_iterations == began + 1
    assert main([*args, "--resume"]) == 0
    assert json.loads((out / "config.json").read_text())["qd"]["exploit_iterations"] == began
    # A key given now is still checked against the run's.
    capsys.readouterr()
    assert main([*args, "--resume", "--set", "seed=5"]) == 2
    assert "different config: seed = 0, not 5" in capsys.readouterr().err
    # A built RunConfig counts as given whole: the changed default is refused, by name.
    with pytest.raises(ValueError, match=f"qd.exploit_iterations = {began}, not {began + 1}"):
        dsage_ray.run(dsage_ray.resolve_config(CONFIG, preset="tiny", overrides=SMALL), local=True, out=out,
                      resume=True)


def test_a_tune_resume_reads_the_config_of_its_trials_latest_checkpoint(tmp_path):
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME
    from dsage_ray.runs import _stored_config

    # One random iteration each (the budget is the tiny preset's n_rand): a checkpoint is all this reads.
    config = dsage_ray.resolve_config(CONFIG, preset="tiny", overrides={**SMALL, "budget": 50})
    assert _stored_config(config, local=False, out=tmp_path) is None
    for seed, number in ((1, 2), (2, 10)):  # checkpoint_000010 is the later one, though it sorts first as text
        run = dsage_ray.run(config.replace(seed=seed), local=True, out=tmp_path / f"s{seed}")
        folder = tmp_path / config.name / "trial_0" / f"checkpoint_{number:06d}"
        folder.mkdir(parents=True)
        (folder / CHECKPOINT_NAME).write_bytes(run.checkpoint.read_bytes())
    assert _stored_config(config, local=False, out=tmp_path).seed == 2
    assert _stored_config(config, local=True, out=tmp_path / "s1").seed == 1
    assert _stored_config(config, local=True, out=tmp_path / "none") is None


def test_an_ablation_resume_compares_only_the_keys_given(monkeypatch):
    import dsage_ray.ray.launch as launch
    from dsage_ray.config import read_config_file

    asked: list[dict] = []
    monkeypatch.setattr(launch, "ablate", lambda config, **kwargs: asked.append(kwargs))
    dsage_ray.ablate(CONFIG, preset="tiny", overrides={"budget": 60}, workers=1, resume=True)
    assert asked[-1]["given"] == set(read_config_file(CONFIG)) | {"preset", "budget", "ray.num_workers"}
    # A new experiment compares nothing; a built RunConfig counts as given whole.
    dsage_ray.ablate(CONFIG, preset="tiny")
    dsage_ray.ablate(dsage_ray.resolve_config(CONFIG, preset="tiny"), resume=True)
    assert asked[-2]["given"] is None and asked[-1]["given"] is None
