"""The pool on a simulated multi-node cluster (in a subprocess: see multinode_check.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


# About a minute (a 4-node cluster started in a subprocess): in `make test-slow`. The default suite keeps the single-node
# checks of the same guarantees: actors replaced without losing a level (test_ray_pool.py) and an agent played from
# its bytes once its file is gone (tests/agents/test_shipping.py).
@pytest.mark.slow
def test_pool_spreads_over_nodes_survives_losing_one_and_needs_no_agent_path_on_any_node():
    env = {**os.environ, "PYTHONPATH": str(ROOT), "RAY_AUTH_MODE": "disabled"}
    proc = subprocess.run([sys.executable, "-m", "tests.ray.multinode_check"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=420)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "multinode ok" in proc.stdout
    assert "agent as data ok" in proc.stdout  # the agent's file deleted after the driver read it
