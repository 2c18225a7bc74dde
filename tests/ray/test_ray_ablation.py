"""``experiments/ablation.py --preset tiny`` end to end, then ``experiments/summarize.py``.

Subprocesses, as a researcher runs them; the ablation starts its own 2-CPU Ray cluster.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.ray.helpers import tensorboard_tags

ROOT = Path(__file__).resolve().parents[2]


def run(*args: str, timeout: int) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "RAY_AUTH_MODE": "disabled", "RAY_ADDRESS": ""}
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)


def test_tiny_ablation_writes_tensorboard_and_summarize_prints_the_table(tmp_path):

    proc = run("experiments/ablation.py", "--preset", "tiny", "--storage", str(tmp_path), "--num-cpus", "2",
               "--name", "tiny", timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    experiment = tmp_path / "tiny"
    trial_dirs = sorted(p.parent for p in experiment.glob("*/params.json"))
    assert len(trial_dirs) == 6  # 3 variants × 2 seeds
    for trial_dir in trial_dirs:
        scalars, images = tensorboard_tags(trial_dir)
        assert "ray/tune/qd_score" in scalars, trial_dir.name
        assert "archive/heatmap" in images, trial_dir.name

    proc = run("experiments/summarize.py", str(experiment), timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = [line for line in proc.stdout.splitlines() if line.startswith("| ")]
    assert lines[0].startswith("| Variant | Runs | QD-score | Coverage (%) | Evaluations to QD-score")
    assert sorted(line.split("|")[1].strip() for line in lines[1:]) == ["dr", "dsage", "map_elites"]
    assert all(line.split("|")[2].strip() == "2" for line in lines[1:])  # both seeds finished
    assert (experiment / "summary.md").exists() and (experiment / "comparison.png").stat().st_size > 0
