"""The GridPath example domain (examples/dsage_ray_gridpath), installed as a package, runs with DSAGE.

The proof that a user brings an environment without touching dsage_ray/: the package is installed like any
plug-in (its ``dsage_ray.domains`` entry point is all dsage_ray learns of it), then run through ``dsage-ray run
--local`` in a fresh process, ``dsage-ray ablate --grid`` in a fresh process on a Ray cluster of its own, whose
trial and simulator actors find it the same way, and the audit and config commands in this process.

It is installed into a folder of its own (``pip install --target``), not into this environment: the suite
leaves the environment as it found it (a user's own install of the example stays, and another pytest worker
never sees this one). The folder is on ``sys.path`` here while this module's tests run, and on ``PYTHONPATH``
for the processes they start.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Iterator

import pytest

from dsage_ray.cli import main
from dsage_ray.domains import unregister_domain

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "dsage_ray_gridpath"
CONFIG = EXAMPLE / "gridpath.toml"


def pip(*args: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "pip", *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"pip {' '.join(args)} failed:\n{proc.stdout[-2000:]}{proc.stderr[-2000:]}"


def with_path(folder: Path) -> dict[str, str]:
    """This process's environment with ``folder`` first on ``PYTHONPATH``, for a process a test starts."""
    paths = [str(folder), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(paths), "RAY_AUTH_MODE": "disabled"}


@contextlib.contextmanager
def example_installed(build: Path) -> Iterator[Path]:
    """The example installed into ``build/site`` (yielded): this process sees it while the block runs, and
    forgets it after."""
    # pip builds in the source folder (build/, *.egg-info): build a copy, not the repository's.
    source = build / "dsage_ray_gridpath"
    shutil.copytree(EXAMPLE, source)
    target = build / "site"
    # Offline with the environment's setuptools when it has one; else pip's isolated build (its cache).
    offline = ["--no-build-isolation", "--no-index"] if importlib.util.find_spec("setuptools") else []
    pip("install", "--quiet", "--no-deps", *offline, "--target", str(target), str(source))
    # Last on the path: the folder holds only the example, and must shadow nothing installed.
    sys.path.append(str(target))
    importlib.invalidate_caches()  # so that the entry-point scan reads the new folder
    unregister_domain("gridpath")  # re-reads the entry points (an earlier test's scan is cached), now with the example
    try:
        yield target
    finally:
        sys.path.remove(str(target))
        for module in [name for name in sys.modules if name.partition(".")[0] == "dsage_ray_gridpath"]:
            del sys.modules[module]
        importlib.invalidate_caches()
        unregister_domain("gridpath")  # forgets the spec and rescans the entry points, now without the example


@pytest.fixture(scope="module")
def gridpath(tmp_path_factory):
    """The example installed into a folder of its own for the module's tests: the folder."""
    with example_installed(tmp_path_factory.mktemp("gridpath")) as target:
        yield target


def test_the_example_is_seen_only_while_its_tests_run(tmp_path):
    """The install is the tests' own: after it, neither this process nor the environment knows the domain
    (unless the environment itself has the example installed: then it still has)."""
    from dsage_ray.domains import domain_names

    def installed_here() -> bool:
        return importlib.util.find_spec("dsage_ray_gridpath") is not None

    environment_has_it = installed_here()
    with example_installed(tmp_path) as target:
        assert "gridpath" in domain_names() and installed_here()
        probe = [sys.executable, "-c", "import dsage_ray_gridpath; print(dsage_ray_gridpath.__file__)"]
        seen = subprocess.run(probe, env=with_path(target), capture_output=True, text=True, timeout=60)
        assert seen.stdout.startswith(str(target)), seen.stderr
    assert str(target) not in sys.path and "dsage_ray_gridpath" not in sys.modules
    assert ("gridpath" in domain_names()) == installed_here() == environment_has_it
    # The environment itself: a new process without the folder finds the example only if it is installed there.
    probe = [sys.executable, "-c", "import importlib.util; print(importlib.util.find_spec('dsage_ray_gridpath'))"]
    fresh = subprocess.run(probe, capture_output=True, text=True, timeout=60).stdout.strip()
    assert (fresh != "None") == environment_has_it


def test_run_local_in_a_fresh_process(gridpath, tmp_path):
    out = tmp_path / "run"
    env = with_path(gridpath)
    proc = subprocess.run([sys.executable, "-m", "dsage_ray.cli", "run", str(CONFIG), "--local", "--preset", "tiny",
                           "--out", str(out)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    config = json.loads((out / "config.json").read_text())
    assert (config["domain"], config["gridpath"]["size"], config["budget"]) == ("gridpath", 8, 40)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics[-1]["evals"] == 40 and metrics[-1]["qd_score"] > 0 and "surrogate_loss" in metrics[-1]
    assert (out / "archive.csv").stat().st_size > 0 and (out / "heatmap.png").stat().st_size > 0
    assert any((out / "elites").glob("*.png"))  # the domain's own render


def test_config_shows_the_plugins_section(gridpath, capsys):
    assert main(["config", str(CONFIG), "--preset", "tiny", "--set", "gridpath.density=0.5"]) == 0
    flat = json.loads(capsys.readouterr().out)
    assert (flat["domain"], flat["gridpath.size"], flat["gridpath.density"]) == ("gridpath", 8, 0.5)
    assert not any(key.startswith(("maze.", "mario.")) for key in flat)


# 29 s: the plug-in's runs in process (the tests above) and Ray's pool and trials in tests/ray/; this adds the two
# together through `dsage-ray ablate`.
@pytest.mark.slow
def test_ablate_grids_a_key_of_the_plugins_section_on_ray(gridpath, tmp_path):
    # In a process of its own: the Ray cluster it starts passes PYTHONPATH on to its actors, where this
    # session's cluster, started before the install, would not. One random iteration a trial (the budget is the
    # tiny preset's n_rand): the pool's evaluations are what this is about (the local run trains the surrogate).
    proc = subprocess.run([sys.executable, "-m", "dsage_ray.cli", "ablate", str(CONFIG), "--preset", "tiny",
                           "--grid", "gridpath.density=0.2,0.4", "--seeds", "1", "--workers", "1", "--set", "budget=20",
                           "--set", "ray.cpus_per_worker=0.5", "--set", "ray.trial_cpus=0.5", "--out", str(tmp_path)],
                          cwd=tmp_path, env=with_path(gridpath), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    trials = sorted(p.parent for p in (tmp_path / "gridpath_dsage").glob("*/params.json"))
    assert len(trials) == 2
    densities = sorted(json.loads((trial / "params.json").read_text())["gridpath.density"] for trial in trials)
    assert densities == [0.2, 0.4]
    for trial in trials:
        last = json.loads((trial / "result.json").read_text().splitlines()[-1])
        # Evaluated by a simulator actor of the trial's pool, which loaded the plug-in itself.
        assert last["evals"] == 20 and last["qd_score"] > 0


def test_audit_collects_reproducible_levels_and_compares_two_agents(gridpath, tmp_path, capsys):
    """``dsage-ray audit --domain gridpath``: the plug-in's AuditSpec and hooks give a collection whose every
    level replays to its numbers, a report with the domain's own column and setting, and ``compare``."""
    import shlex

    from dsage_ray.audit.collection_file import load_collection
    from dsage_ray.audit.compare import compare_agents

    out = tmp_path / "audit"
    assert main(["audit", "--domain", "gridpath", "--agent", "bfs:16", "--preset", "tiny", "--seed", "1", "--local",
                 "--out", str(out)]) == 0
    collection = out / "collection"
    c = load_collection(collection)
    assert (c["domain"], c["agent"], c["objective"], c["size"]) == ("gridpath", "bfs:16", "failure", 8)
    levels = c["levels"]
    assert levels and any(lv["success_rate"] == 0 for lv in levels)  # the search found levels where it gives up
    for lv in levels:
        # A reachable goal: the agent fails exactly when the path needs more than 16 moves.
        assert lv["success_rate"] == float(lv["path_length"] - 1 <= 16) and lv["objective"] == 1 - lv["success_rate"]
        capsys.readouterr()
        assert main(shlex.split(lv["reproduce"])[1:]) == 0
        again = json.loads(capsys.readouterr().out)
        assert (again["success_rate"], again["path_length"]) == (lv["success_rate"], lv["path_length"])

    page = (collection / "report.html").read_text()
    assert "<dt>grid</dt><dd>8x8 cells</dd>" in page and ">path length</button></th>" in page
    assert "title='cells on the shortest path from the top-left corner to the bottom-right one of this 8x8 grid" in page
    assert ">mean path length</button></th>" in page  # the region table averages the declared column

    # B never gives up: better exactly where A failed; the path is the level's, whoever walks it.
    comparison = compare_agents("bfs:16", "bfs", collection_dir=collection)
    recorded = {lv["id"]: lv for lv in levels}
    for row in comparison["levels"]:
        assert row["success_a"] == recorded[row["id"]]["success_rate"] and row["success_b"] == 1.0
        assert row["path_length_a"] == row["path_length_b"] == recorded[row["id"]]["path_length"]
        assert row["verdict"] == ("better" if row["success_a"] == 0 else "same")
    assert main(["compare", "--agent", "bfs:16", "--agent", "bfs", "--collection", str(collection)]) == 0
    assert "mean path length A" in capsys.readouterr().out


def test_audit_refuses_an_agent_kind_the_domain_does_not_play(gridpath, tmp_path, capsys):
    assert main(["audit", "--domain", "gridpath", "--agent", "dcd:accel", "--local", "--out", str(tmp_path / "a")]) == 2
    assert capsys.readouterr().err.strip() == (
        "dsage-ray audit: error: domain 'gridpath' does not play 'dcd' agents (agent spec 'dcd:accel'); its agents: "
        "bfs[:MOVES]; 'dcd' agents are played by: maze")
    assert not (tmp_path / "a").exists()
