"""One small Ray cluster for all Ray tests (starting one costs seconds and ~0.6 GB)."""

from __future__ import annotations

import os

import pytest

# Must be set before Ray starts; the test machine has no token set up.
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
# Tune prints a progress table every few seconds otherwise.
os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")


@pytest.fixture(scope="session")
def ray_session():
    """A 2-CPU local cluster shared by the session; the multi-node test runs in a subprocess."""
    import ray
    import torch

    # The reference runs happen in this process; with torch's default of one thread per core
    # they crawl when the cores are shared (measured: 4.5 min instead of 24 s).
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    if not ray.is_initialized():
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()
    torch.set_num_threads(threads)
