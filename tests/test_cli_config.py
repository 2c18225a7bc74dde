"""``dsage-ray config``: the resolved run config as flat JSON, without running (or importing) anything else."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from dsage_ray.cli import main
from dsage_ray.config import RunConfig

REPO_ROOT = Path(__file__).resolve().parents[1]
MAZE_CONFIGS = sorted((REPO_ROOT / "experiments" / "configs").glob("maze_*.toml"))


def config_output(capsys, *args: str) -> dict:
    assert main(["config", *map(str, args)]) == 0
    out = capsys.readouterr().out
    keys = [line.split('"')[1] for line in out.splitlines()[1:-1]]
    assert keys == sorted(keys), "keys are printed sorted, one per line"
    return json.loads(out)


def test_prints_the_resolved_flat_config(capsys):
    path = REPO_ROOT / "experiments" / "configs" / "maze_dsage.toml"
    printed = config_output(capsys, path, "--preset", "cpu", "--set", "surrogate.epochs=50",
                            "--set", "selection.block=[8, 6]")
    expected = RunConfig.from_file(path, {"preset": "cpu", "surrogate.epochs": 50, "selection.block": [8, 6]})
    assert printed == expected.to_flat()
    # Defaults, then the cpu preset, then the variant, then --set: each layer shows.
    assert printed["budget"] == 4_000 and printed["qd.exploit_iterations"] == 300
    assert printed["surrogate.kind"] == "two_stage" and printed["selection.method"] == "downsample"
    assert printed["surrogate.epochs"] == 50 and printed["selection.block"] == [8, 6]
    assert all("." in key or key in RunConfig.__dataclass_fields__ for key in printed)


@pytest.mark.parametrize("path", MAZE_CONFIGS, ids=[p.stem for p in MAZE_CONFIGS])
def test_every_maze_experiment_config_audits_the_shipped_accel_agent(capsys, path):
    printed = config_output(capsys, path, "--preset", "cpu")
    assert printed["maze.agent"] == "dcd:accel"
    assert printed["variant"] == path.stem.removeprefix("maze_")


@pytest.mark.parametrize("args, message", [
    (["--set", "surrogate.epoch=5"], "surrogate.epoch: unknown config key"),
    (["--set", "surrogate.precision=fp16"], "surrogate.precision: must be 'auto', 'fp32' or 'bf16'"),
    (["--preset", "gpu"], "preset: unknown preset 'gpu'"),
    (["--set", "budget"], "expected key=value"),
])
def test_bad_input_is_one_error_line(capsys, args, message):
    assert main(["config", str(MAZE_CONFIGS[0]), *args]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("dsage-ray config: error: ") and message in captured.err
    assert captured.err.count("\n") == 1


def test_runs_nothing_and_imports_neither_ray_nor_torch():
    # A fresh interpreter: other tests have imported everything in this one.
    code = ("import sys; from dsage_ray.cli import main; rc = main(sys.argv[1:]); "
            "heavy = [m for m in ('ray', 'torch', 'ribs') if m in sys.modules]; "
            "print('HEAVY', heavy, file=sys.stderr); sys.exit(rc or bool(heavy))")
    proc = subprocess.run([sys.executable, "-c", code, "config", str(MAZE_CONFIGS[0]), "--preset", "tiny"],
                          cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "HEAVY []" in proc.stderr
    assert json.loads(proc.stdout)["preset"] == "tiny"


def test_a_reader_that_stops_early_is_not_an_error():
    """``dsage-ray config … | head -1``: the closed pipe ends the command quietly with exit 0."""
    path = REPO_ROOT / "experiments" / "configs" / "maze_dsage.toml"
    proc = subprocess.Popen([sys.executable, "-m", "dsage_ray.cli", "config", str(path)], cwd=REPO_ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0)
    assert proc.stdout.read(1) == b"{"
    proc.stdout.close()
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 0 and b"error" not in stderr, stderr


@pytest.mark.parametrize("text, seconds", [("90", 90.0), ("90s", 90.0), ("10m", 600.0), ("1.5h", 5400.0),
                                           ("0", 0.0), (" 2M ", 120.0)])
def test_time_budget_flag_takes_seconds_or_a_duration(capsys, text, seconds):
    printed = config_output(capsys, MAZE_CONFIGS[0], "--preset", "tiny", f"--time-budget={text}")
    assert printed["time_budget"] == seconds
    assert printed["budget"] == RunConfig.build({"preset": "tiny"}).budget  # the evaluation budget still applies


@pytest.mark.parametrize("text", ["ten minutes", "10min", "-5", "1h30m", ""])
def test_a_bad_time_budget_names_the_flag(capsys, text):
    with pytest.raises(SystemExit) as exit_:
        main(["config", str(MAZE_CONFIGS[0]), f"--time-budget={text}"])
    assert exit_.value.code == 2
    assert (f"dsage-ray config: error: argument --time-budget: expected seconds or a duration such as 90s, 10m "
            f"or 1.5h, got {text!r}") in capsys.readouterr().err


@pytest.mark.parametrize("command", [["run", "x.toml"], ["ablate", "x.toml"], ["audit"]])
def test_run_ablate_and_audit_take_a_time_budget(command):
    from dsage_ray.cli import build_parser

    assert build_parser().parse_args([*command, "--time-budget", "10m"]).time_budget == 600.0


def test_audit_hands_the_time_budget_to_its_search(monkeypatch):
    import dsage_ray.audit.run as audit_run

    class Stop(Exception):
        """Raised instead of searching."""

    seen = {}

    def no_search(*args, **kwargs):
        seen.update(kwargs, args=args)
        raise Stop

    monkeypatch.setattr(audit_run, "run_audit", no_search)
    with pytest.raises(Stop):
        main(["audit", "--agent", "builtin:random", "--preset", "tiny", "--local", "--time-budget", "2m",
              "--set", "n_rand=7"])
    # The search gets either the built config or the keys it is built from.
    keys = seen["args"][0].to_flat() if seen["args"] else seen["overrides"]
    assert keys["time_budget"] == 120.0 and keys["n_rand"] == 7
