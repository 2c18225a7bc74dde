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
def agent_plugin_site(tmp_path_factory):
    """The folder that the test agent plug-in (tests/fixtures/agent_plugin) is installed into for the session.

    Its own folder (``pip install --target``, tests/plugin_package.py), not this environment: the suite leaves
    the environment as it found it, and each pytest worker has its own copy, so none waits on or removes
    another's. ``None`` without pip: the plug-in tests skip, and Ray's tests run without it.
    """
    from tests import plugin_package

    if importlib.util.find_spec("pip") is None:
        return None
    return plugin_package.install(tmp_path_factory.mktemp("agent_plugin"))


@pytest.fixture(scope="session")
def ray_session(agent_plugin_site):
    """One 2-CPU local cluster for every test that needs Ray (starting one costs seconds and ~0.6 GB).

    Its workers have the test agent plug-in's folder on ``PYTHONPATH`` (an actor reads the entry points
    itself, and a worker's path is set when the cluster starts, before any test asks for the plug-in); only
    a plug-in kind named in a spec loads from it. The multi-node test runs in a subprocess.
    """
    import ray
    import torch

    from dsage_ray.ray.session import start_ray
    from tests import plugin_package

    # The reference runs happen in this process; with torch's default of one thread per core
    # they crawl when the cores are shared (measured: 4.5 min instead of 24 s).
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    # The job's env_vars reach every actor (merged with those an actor sets itself, e.g. the pool's threads).
    plugin_path = {"PYTHONPATH": plugin_package.python_path(agent_plugin_site)} if agent_plugin_site else None
    # As the CLI starts it: on 127.0.0.1 (tests/ray/test_session.py).
    start_ray(num_cpus=2, log_to_driver=False, runtime_env=plugin_path and {"env_vars": plugin_path})
    yield ray
    ray.shutdown()
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def agent_plugin(agent_plugin_site):
    """The test agent plug-in, found by this process for the session; yields the kind it provides.

    Installed into a folder of its own (``agent_plugin_site``), on ``sys.path`` here and on ``PYTHONPATH`` for
    Ray's workers (``ray_session``), so that both find it exactly as they would find a user's package: through
    its entry point in the folder's ``dist-info``.
    """
    from tests import plugin_package

    if agent_plugin_site is None:
        pytest.skip("pip is not installed in this environment")
    with plugin_package.on_path(agent_plugin_site):
        yield plugin_package.KIND


#: Files whose tests take most of the suite's time (Tune experiments, Ray pools, JVM runs, subprocess runs), the
#: slowest first (``--durations`` of a ``make test`` run). ``make test`` runs two pytest workers that take whole files
#: in collection order (``--no-loadscope-reorder``); handing these out first keeps both busy to the end instead of
#: leaving one worker alone with a slow file. The files after them take under 20 s each.
SLOW_FILES_FIRST = (
    "tests/ray/test_ray_trainable.py",
    "tests/ray/test_ray_pool.py",
    "tests/ray/test_mode_equality.py",
    "tests/ray/test_ray_progress.py",
    "tests/audit/test_audit.py",
    "tests/domains/maze/agents/test_rllib.py",
    "tests/core/test_warm_start.py",
    "tests/core/test_runner.py",
    "tests/audit/test_audit_ray.py",
    "tests/test_api.py",
    "tests/test_summarize.py",
    "tests/benchmarks/test_surrogate_benchmark.py",
    "tests/integrations/test_rllib.py",
    "tests/test_errors.py",
    "tests/core/test_golden.py",
    "tests/ray/test_ray_mario.py",
    "tests/examples/test_gridpath.py",
    "tests/audit/test_report_browser.py",
    "tests/audit/test_mario_audit.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(SLOW_FILES_FIRST)}
    root = config.rootpath

    def order(item):
        name = item.path.relative_to(root).as_posix() if item.path.is_relative_to(root) else str(item.path)
        return rank.get(name, len(rank))

    items.sort(key=order)  # stable: every file keeps its own tests' order
