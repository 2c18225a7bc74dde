"""Runs the simulator pool on a simulated 3-node cluster; exits 0 when every check passes.

A separate process because ``ray.cluster_utils.Cluster`` cannot share a process with the test
session's ``ray.init``. Run by ``test_ray_cluster.py``; also runnable by hand.
"""

from __future__ import annotations

import os
import sys
import threading

os.environ.setdefault("RAY_AUTH_MODE", "disabled")

import numpy as np  # noqa: E402
import ray  # noqa: E402
from ray.cluster_utils import Cluster  # noqa: E402

from dsage_ray.core.evaluation import InProcessEvaluator  # noqa: E402
from dsage_ray.ray.pool import SimulatorPool  # noqa: E402
from tests.ray.helpers import SlowBitmapDomain, slow_bitmap_domain, small_config  # noqa: E402


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
        return 0
    finally:
        ray.shutdown()
        cluster.shutdown()


if __name__ == "__main__":
    sys.exit(main())
