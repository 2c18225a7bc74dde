"""``experiments/ablation.py --preset tiny --grid ...`` end to end, then ``experiments/summarize.py``.

Subprocesses, as a researcher runs them; the ablation starts its own 2-CPU Ray cluster.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.ray.helpers import tensorboard_tags

ROOT = Path(__file__).resolve().parents[2]


def run(*args: str, timeout: int) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "RAY_AUTH_MODE": "disabled", "RAY_ADDRESS": ""}
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)


# A fresh 2-CPU cluster and four trials: the ablation script on Ray is also covered by
# tests/examples/test_gridpath.py, and summarize's tables by tests/test_summarize.py.
@pytest.mark.slow
def test_tiny_grid_ablation_writes_tensorboard_and_summarize_prints_a_row_per_grid_point(tmp_path):
    proc = run("experiments/ablation.py", "--preset", "tiny", "--storage", str(tmp_path), "--num-cpus", "2",
               "--name", "tiny", "--set", "budget=70", "--grid", "variant=dsage,map_elites",
               "--grid", "qd.batch_size=10,20", "--seeds", "1", timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "tiny: variant (2) × qd.batch_size (2) × seed (1) via tuner" in proc.stdout
    experiment = tmp_path / "tiny"
    trial_dirs = sorted(p.parent for p in experiment.glob("*/params.json"))
    assert len(trial_dirs) == 4  # 2 variants × 2 batch sizes
    for trial_dir in trial_dirs:
        scalars, images = tensorboard_tags(trial_dir)
        assert "dsage/qd_score" in scalars and not any(t.startswith("ray/tune/") for t in scalars), trial_dir.name
        assert "archive/heatmap" in images, trial_dir.name

    proc = run("experiments/summarize.py", str(experiment), timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # The first table is the equal-evaluation one (the equal-wall-time table follows it).
    lines = []
    for line in proc.stdout.splitlines():
        if line.startswith("|"):
            lines.append(line)
        elif lines:
            break
    lines = [line for line in lines if not line.startswith("|---")]
    assert lines[0].startswith("| Variant | qd.batch_size | Runs | QD-score | Coverage (%) | Evaluations to QD-score")
    cells = sorted([c.strip() for c in line.strip("|").split("|")][:3] for line in lines[1:])
    # Each grid point is one finished run.
    assert cells == [["dsage", "10", "1"], ["dsage", "20", "1"], ["map_elites", "10", "1"], ["map_elites", "20", "1"]]
    assert (experiment / "summary.md").exists() and (experiment / "comparison.png").stat().st_size > 0
