"""Suite-wide test settings."""

import contextlib
import fcntl
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
    actors find it exactly as they would find a user's package (tests/plugin_package.py). ``make test``'s
    two pytest workers share the environment, so the install is counted: the first user installs it and the
    last one uninstalls it.
    """
    from tests import plugin_package

    if importlib.util.find_spec("pip") is None:
        pytest.skip("pip is not installed in this environment")
    with _plugin_users(tmp_path_factory, +1) as users:
        if users == 1:
            plugin_package.install(tmp_path_factory.mktemp("agent_plugin"))
    try:
        yield plugin_package.KIND
    finally:
        with _plugin_users(tmp_path_factory, -1) as users:
            if users == 0:
                plugin_package.uninstall()


@contextlib.contextmanager
def _plugin_users(tmp_path_factory, change: int):
    """Changes the count of this run's workers using the installed plug-in; holds a lock across the block."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # one run's workers share the parent
    with open(shared / "agent_plugin.lock", "a+") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        count_file = shared / "agent_plugin.users"
        users = int(count_file.read_text()) if count_file.exists() else 0
        users += change
        count_file.write_text(str(users))
        try:
            yield users
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


#: Files whose tests take most of the suite's time (Tune experiments, Ray pools, JVM runs). ``make test`` runs
#: two pytest workers that take whole files in collection order; handing these out first keeps both busy to the
#: end instead of leaving one worker alone with the slowest files.
SLOW_FILES_FIRST = (
    "tests/ray/test_ray_trainable.py",
    "tests/ray/test_mode_equality.py",
    "tests/ray/test_ray_mario.py",
    "tests/test_api.py",
    "tests/audit/test_mario_audit.py",
    "tests/ray/test_ray_progress.py",
    "tests/audit/test_audit_ray.py",
    "tests/test_summarize.py",
    "tests/ray/test_storage.py",
    "tests/domains/maze/agents/test_rllib.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(SLOW_FILES_FIRST)}
    root = config.rootpath

    def order(item):
        name = item.path.relative_to(root).as_posix() if item.path.is_relative_to(root) else str(item.path)
        return rank.get(name, len(rank))

    items.sort(key=order)  # stable: every file keeps its own tests' order
