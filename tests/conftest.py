"""Suite-wide test settings."""

import importlib.util
import os

import pytest
import torch

os.environ.setdefault("RAY_AUTH_MODE", "disabled")
# Tune prints a progress table every few seconds otherwise.
os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")


@pytest.fixture(autouse=True, scope="session")
def one_torch_thread():
    """One intra-op thread per test process: CI has 2 cores and Ray workers share them.

    With 2 threads on a busy 2-core machine torch's threads wait on each other at every op and
    small models run 3–4× slower.
    """
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.fixture(scope="session")
def ray_session():
    """One 2-CPU local cluster for every test that needs Ray (starting one costs seconds and ~0.6 GB).

    The multi-node test runs in a subprocess.
    """
    import ray
    import torch

    from dsage_ray.ray.session import start_ray

    # The reference runs happen in this process; with torch's default of one thread per core
    # they crawl when the cores are shared (measured: 4.5 min instead of 24 s).
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    start_ray(num_cpus=2, log_to_driver=False)  # as the CLI starts it: on 127.0.0.1 (tests/ray/test_session.py)
    yield ray
    ray.shutdown()
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def agent_plugin(tmp_path_factory):
    """The test agent plug-in (tests/fixtures/agent_plugin) installed as a package; yields the kind it provides.

    Installed with pip into this environment for the session and uninstalled after it, so that Ray's
    actors find it exactly as they would find a user's package (tests/plugin_package.py).
    """
    from tests import plugin_package

    if importlib.util.find_spec("pip") is None:
        pytest.skip("pip is not installed in this environment")
    plugin_package.install(tmp_path_factory.mktemp("agent_plugin"))
    try:
        yield plugin_package.KIND
    finally:
        plugin_package.uninstall()
