"""The same config gives the same run in every execution mode.

In-process (``dsage-ray run --local``), one Tune trial with 1 simulator actor and one with 2 actors
(results arriving out of order, one solution per task) must write byte-identical ``archive.csv``
files and the same metrics, for DSAGE and MAP-Elites (the other DSAGE variants differ from DSAGE only in
keys the runner reads, not in how the modes drive it). DSAGE's two-actor trial runs
pipelined (``pipeline = true``: the surrogate trains while the pool evaluates) and is compared with a
pipelined in-process run; DSAGE's trials and MAP-Elites' one-actor trial screen their candidates
(``selection.screen_episodes``), as their in-process twins do. The in-process run is
started with a torch thread count other than the config's, as a user's shell would have it.

The default suite runs DSAGE's two-actor case, which has all of it: actors out of order, the pipeline and the
screen. The other three are ``slow`` (``-m slow``): each adds a Tune trial and an in-process twin (about 25 s)."""

from __future__ import annotations

import json

import pytest
import torch
from ray import tune

from dsage_ray.config import RunConfig
from dsage_ray.core.loop import run_locally
from dsage_ray.ray.experiment import grid_param_space, run_experiment
from tests.fakes import SMALL_RUN

pytestmark = pytest.mark.usefixtures("ray_session")

#: The shared small run on the real Maze (its archive and blocks, not the bitmap's) with the fast
#: deterministic agent: MAP-Elites' random batches and iterations; DSAGE's run (:data:`DSAGE_RUN`) shorter. A
#: checkpoint and images at the end only, as they cost time and change nothing. Small CPU reservations, so that the trials share the 2-CPU
#: test cluster (their processes mostly wait on each other's start-up).
CONFIG = {
    **{key: value for key, value in SMALL_RUN.items() if key not in ("maze.archive_dims", "selection.block")},
    "preset": "tiny",
    "maze.agent": "builtin:wall_follower",
    "maze.episodes": 2,
    "budget": 58,
    "image_every": 100,
    "ray.trial_cpus": 0.5,
    "ray.cpus_per_worker": 0.25,
    "experimental.chunk_size": 1,
}
VARIANTS = ("dsage", "map_elites")
#: DSAGE's runs: 20 random levels and about a dozen outer iterations of one to four picks (SMALL_RUN's 40 random
#: levels only made each run twice as long).
DSAGE_RUN = {"n_rand": 20, "budget": 38}
WORKERS = (1, 2)
#: What the screened trials add: a screen of one episode a candidate. It plays where the proposer runs (the trial's
#: process) and draws its seeds from the run's stream, so it must not make the modes differ.
SCREEN = {"selection.screen_episodes": 1}
#: MAP-Elites screens only once its random batches are done: its screened runs go on to this budget (DSAGE screens
#: from its first surrogate iteration on, and each of its screened iterations picks only a few levels).
MAP_ELITES_SCREENED_BUDGET = 100


def screened(variant: str, workers: int) -> bool:
    """DSAGE's trials and the one-actor trials screen; MAP-Elites' two-actor trial does not."""
    return variant == "dsage" or workers == 1


def pipelined(variant: str, workers: int) -> bool:
    return variant == "dsage" and workers == 2


def case_config(variant: str, workers: int) -> dict:
    """The keys of trial ``(variant, workers)`` beyond :data:`CONFIG`, which its in-process twin runs with."""
    keys = {"variant": variant, "pipeline": pipelined(variant, workers), **(DSAGE_RUN if variant == "dsage" else {})}
    if screened(variant, workers):
        keys |= {**SCREEN, **({"budget": MAP_ELITES_SCREENED_BUDGET} if variant == "map_elites" else {})}
    return keys


#: The case of the default suite; the others are ``slow``.
DEFAULT_CASE = ("dsage", 2)
CASES = [pytest.param(variant, workers, marks=[] if (variant, workers) == DEFAULT_CASE else [pytest.mark.slow])
         for variant in VARIANTS for workers in WORKERS]


def selected_cases(session) -> list[tuple[str, int]]:
    """The cases this session runs (``-m`` and ``-k`` deselect before fixtures start)."""
    return sorted({(item.callspec.params["variant"], item.callspec.params["workers"]) for item in session.items
                   if item.path.name == "test_mode_equality.py" and hasattr(item, "callspec")})


@pytest.fixture(scope="module")
def tune_trials(request, tmp_path_factory) -> dict[tuple[str, int], dict]:
    """``(variant, ray.num_workers)`` → the trial's resolved config, archive.csv and metrics.

    One Tune experiment for every selected case: a Tune start costs more than any of these runs.
    """
    cases = selected_cases(request.session)
    base = RunConfig.build({**CONFIG, "variant": "dsage"})
    space = grid_param_space(base, {"variant": sorted({v for v, _ in cases}),
                                    "ray.num_workers": sorted({w for _, w in cases})})
    for key in ("pipeline", *SCREEN, *DSAGE_RUN):
        space[key] = tune.sample_from(lambda spec, key=key: RunConfig.build(
            {**CONFIG, **case_config(spec.config["variant"], spec.config["ray.num_workers"])}).to_flat()[key])
    experiment = run_experiment(space, name="modes", storage_path=tmp_path_factory.mktemp("tune"), max_failures=0)
    trials = {}
    for trial in experiment.trials:
        trials[trial.config.variant, trial.config.ray.num_workers] = outputs(trial.path, trial.config)
    assert set(cases) <= set(trials)
    return trials


def outputs(run_dir, config: RunConfig) -> dict:
    """What must match across modes: the config (Ray keys aside), the archive and the metrics (timings aside);
    and the raw ``history``, timings included, which is read but not compared."""
    history = json.loads((run_dir / "metrics.json").read_text())
    return {
        "config": {k: v for k, v in config.to_flat().items() if not k.startswith("ray.")},
        "archive.csv": (run_dir / "archive.csv").read_bytes(),
        # Per-phase times (time_*) and the cumulative wall and CPU time differ from run to run.
        "metrics": [{k: v for k, v in m.items() if not k.startswith("time_") and k not in ("wall_time", "cpu_time")}
                    for m in history],
        "history": history,
    }


@pytest.mark.parametrize("variant, workers", CASES)
def test_in_process_and_tune_with_one_or_two_actors_write_the_same_archive(variant, workers, tune_trials, tmp_path):
    config = RunConfig.build({**CONFIG, **case_config(variant, workers)})
    assert config.torch_threads == 1
    caller_threads = torch.get_num_threads()
    torch.set_num_threads(2)  # not the config's count: the runner pins it during each step
    try:
        run_locally(config, out_dir=tmp_path)
        assert torch.get_num_threads() == 2  # and gives the caller's back
    finally:
        torch.set_num_threads(caller_threads)
    local = outputs(tmp_path, config)
    assert len(local["metrics"]) >= 3  # a surrogate variant trains at least twice
    if config.uses_surrogate:
        assert "surrogate_loss" in local["metrics"][-1]
    if screened(variant, workers):
        assert sum(row.get("selection_screened", 0) for row in local["metrics"]) > 0
    trial = tune_trials[variant, workers]
    assert trial["config"] == local["config"]
    assert trial["metrics"] == local["metrics"]
    assert trial["archive.csv"] == local["archive.csv"]
    if pipelined(variant, workers):  # the surrogate worked while each batch after the first was out
        overlapped = [row.get("time_overlapped", 0.0) for row in trial["history"]]
        assert overlapped[0] == 0.0 and all(seconds > 0 for seconds in overlapped[1:-1])
