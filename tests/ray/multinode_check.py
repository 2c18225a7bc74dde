"""Runs the simulator pool on a simulated 3-node cluster; exits 0 when every check passes.

A separate process because ``ray.cluster_utils.Cluster`` cannot share a process with the test
session's ``ray.init``. Run by ``test_ray_cluster.py``; also runnable by hand.
"""

from __future__ import annotations

import os
import sys
import threading
import time

os.environ.setdefault("RAY_AUTH_MODE", "disabled")

import numpy as np  # noqa: E402
import ray  # noqa: E402
from ray.cluster_utils import Cluster  # noqa: E402

from dsage_ray.core.evaluation import InProcessEvaluator  # noqa: E402
from dsage_ray.ray.pool import SimulatorPool  # noqa: E402
from tests.ray.helpers import SlowBitmapDomain, slow_bitmap_domain, small_config  # noqa: E402


def check_agent_travels_as_data(cluster: Cluster, workers: list) -> None:
    """A Maze pool whose agent file is deleted once the driver has read it: every actor, a replacement on another
    node included, plays the driver's agent from the bytes Ray moved, and none opens the path."""
    import shutil
    import tempfile
    from pathlib import Path

    from dsage_ray.agents.loader import ASSETS_DIR
    from dsage_ray.domains.maze.agents import load_maze_agent
    from dsage_ray.agents.shipping import config_agent_specs, pack_agent_files
    from dsage_ray.config import RunConfig
    from dsage_ray.domains import build_domain

    folder = Path(tempfile.mkdtemp(prefix="dsage_ray_agent_test_"))
    shutil.copy(ASSETS_DIR / "accel" / "model_20000.tar", folder / "mine.tar")
    config = RunConfig.build({"domain": "maze", "maze.agent": f"dcd:{folder / 'mine.tar'}", "maze.episodes": 4,
                              "experimental.chunk_size": 1})
    load_maze_agent(config.domain_config.agent)  # the driver loads it once (preflight)...
    files = pack_agent_files(config_agent_specs(config.to_dict()))  # ... and reads its bytes
    shutil.rmtree(folder)  # gone from the only disk that had it
    # The head and the worker left by the first check hold the two actors; one more node takes the replacement.
    workers = [node for node in workers if node in cluster.worker_nodes] + [cluster.add_node(num_cpus=1)]
    cluster.wait_for_nodes()
    domain = build_domain(config)
    solutions = domain.random_solutions(12, np.random.default_rng(3))
    seeds = list(range(12))
    with SimulatorPool(config=config, num_workers=2, cpus_per_worker=1.0, agent_files=files) as pool:
        assert len({info["node_id"] for info in pool.actor_info}) == 2
        first = pool(solutions, seeds)
        assert not any(result.failed for result in first), [r.error for r in first if r.failed]
        victim = next(node for node in workers if node.node_id in {i["node_id"] for i in pool.actor_info})
        cluster.remove_node(victim, allow_graceful=False)
        # The node's processes die a moment after it is removed: evaluate until the pool has seen its actor die and
        # replaced it (a replacement that, like every actor, has never had the file).
        deadline = time.monotonic() + 120
        while pool.stats.actor_deaths == 0 and time.monotonic() < deadline:
            again = pool(solutions, seeds)
            assert [r.objective for r in again] == [r.objective for r in first]
        assert pool.stats.actor_deaths >= 1, pool.stats
        again = pool(solutions, seeds)  # on the replacement
        assert [r.objective for r in again] == [r.objective for r in first]


def main() -> int:
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    workers = [cluster.add_node(num_cpus=1) for _ in range(2)]
    cluster.wait_for_nodes()
    ray.init(address=cluster.address, log_to_driver=False)
    try:
        # Long enough (~1.5 s on 2 actors) that the node loss at 0.3 s lands mid-batch even on an idle machine.
        solutions = SlowBitmapDomain().random_solutions(120, np.random.default_rng(7))
        seeds = list(range(100, 220))
        expected = InProcessEvaluator(domain=SlowBitmapDomain(base_s=0, extra_s=0))(solutions, seeds)
        with SimulatorPool(config=small_config(), num_workers=2, cpus_per_worker=1.0,
                           domain_factory=slow_bitmap_domain) as pool:
            nodes = {info["node_id"] for info in pool.actor_info}
            assert len(nodes) == 2, f"1-CPU actors on 1-CPU nodes must spread over 2 nodes, got {nodes}"
            results = pool(solutions, seeds)
            assert [r.objective for r in results] == [r.objective for r in expected]

            # Lose a whole worker node mid-batch: its actor is replaced on the spare node.
            hosts = {node.node_id: node for node in workers}
            victim = next(hosts[n] for n in nodes if n in hosts)
            killer = threading.Timer(0.3, lambda: cluster.remove_node(victim, allow_graceful=False))
            killer.start()
            results = pool(solutions, seeds)
            killer.join()
            assert pool.stats.actor_deaths == 1, pool.stats
            assert all(a.objective == b.objective and np.array_equal(a.occupancy, b.occupancy)
                       for a, b in zip(results, expected))
            assert pool.stats.evaluations == 2 * len(solutions)
        print("multinode ok:", pool.stats)
        check_agent_travels_as_data(cluster, workers)
        print("agent as data ok")
        return 0
    finally:
        ray.shutdown()
        cluster.shutdown()


if __name__ == "__main__":
    sys.exit(main())
