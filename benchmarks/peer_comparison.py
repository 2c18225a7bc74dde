"""The tools people test RL policies with, beside our searches, on the peers' own task (issue 62, item 2).

Every arm searches the task's parameter box (``--space lunarlander_fault``: the initial force in [-1000, 1000]²)
with the same agent and the same episode code: each level any arm plays goes through dsage_ray's gym domain
(``domain.evaluate``, one deterministic episode), recorded by one :class:`Ledger`. The ledger counts, after any
number of episodes or CPU seconds:

* faults: distinct failing levels (a crash: last reward -100);
* fault cells: distinct cells of the peers' 50 × 50 grid (x at first leg contact × vertical speed then, the
  space's archive) that hold a fault;
* episodes, and CPU seconds: :func:`time.process_time` of this process (every thread) plus its waited-for children
  (:func:`os.times`); no arm starts a child process, so it is this process's CPU.

The arms:

* ours: ``dsage`` (the audit's DSAGE search, the gym ``demo`` preset at the episode budget), ``map_elites``,
  ``cross_entropy`` and ``halton`` (the gym domain's variants), all through the runner (:class:`dsage_ray.core.runner.DSAGE`);
* ``rt``, ``fuzzer``, ``mdpfuzz``: random testing, Fuzzer and MDPFuzz of the ``mdpfuzz`` package (PyPI, the
  ``peers`` extra), through a small :class:`mdpfuzz.executor.Executor` that plays through the ledger;
* ``tpe``: Ray Tune's ``OptunaSearch`` (TPE) minimising the return, driven through its Searcher interface
  (``suggest`` / ``on_trial_complete``) in this process: Tune's trial runner would cost more per trial than an
  episode does;
* ``indago``: Indago's idea, re-implemented: a pass/fail classifier (a random forest) trained on the levels played
  so far guides a genetic algorithm, and only its top picks are played.

Each run of an arm on a seed goes to the episode budget and, with ``--cpu-from FILE`` (the dsage runs' records), on
until it has also spent the CPU seconds DSAGE spent on that seed, so one run gives both the equal-episodes and the
equal-CPU counts. Runs append one JSON line each to ``--out``; ``--table`` prints the headline table::

    nice -n 5 python benchmarks/peer_comparison.py --arms dsage --seeds 100 101 102 103 104 --out runs.jsonl
    nice -n 5 python benchmarks/peer_comparison.py --arms rt fuzzer mdpfuzz tpe indago map_elites \\
        --seeds 100 101 102 103 104 --cpu-from runs.jsonl --out runs.jsonl
    python benchmarks/peer_comparison.py --table runs.jsonl
"""

from __future__ import annotations

import argparse
import dataclasses
import gzip
import json
import os
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from metrics import format_mean_se, mean_se  # noqa: E402  (this folder's helpers)

OURS = ("dsage", "map_elites", "cross_entropy", "halton")

#: The peers' tasks: the shipped space, the agent (read at run time, never committed) and the peers' mutation
#: intensity (in the parameters' units). LunarLander: Mazouni et al.'s QD task (AST 2024); the zoo's PPO never
#: crashes on it under Gymnasium 1.x, the zoo's DQN does (docs/results/peers/record.md). CartPole: MDPFuzz's, as
#: their replication study (Mazouni et al., 2025) runs it, with its own DQN (replication/cart/models/10140000.zip of
#: QuentinMaz/MDPFuzz_Replicability_Study_Artifact; the record says how to take it out).
TASKS: dict[str, dict[str, Any]] = {
    "lunarlander": {"space": "lunarlander_fault", "agent": "sb3:../shared/models/rl_zoo/dqn/LunarLander-v2_1",
                    "mdpfuzz_intensity": 5.0},
    "cartpole": {"space": "cartpole_initial_state", "agent": "sb3:/tmp/cart_dqn/10140000.zip?greedy=1",
                 "mdpfuzz_intensity": 0.01},
    # Mazouni et al.'s Taxi task (AST 2024): their Q-table on their map (experiments/taxi_large_map_qtable.npy and
    # map_large.txt of QuentinMaz/QD_Based_Testing_RL, taken out at run time as record.md says); their mutation
    # redraws one coordinate, nearer values likelier.
    "taxi": {"space": "taxi_large_fault", "agent": "qtable:/tmp/taxi/qtable.npy",
             "env_args": ("map_file=/tmp/taxi/map_large.txt",), "mdpfuzz_mutation": "one_coordinate"},
}
PEERS = ("rt", "fuzzer", "mdpfuzz", "tpe", "indago")
#: Episodes of each arm's untimed warm-up run: past the demo preset's 60 random levels, so DSAGE's surrogate trains.
WARM_UP_EPISODES = 90


@dataclass
class Config:
    """One invocation: which arms on which seeds, the budgets, and each arm's hyper-parameters."""

    #: One of :data:`TASKS`: the defaults of ``space``, ``agent`` and ``mdpfuzz_intensity``.
    task: str = "lunarlander"
    agent: str = TASKS["lunarlander"]["agent"]
    space: str = TASKS["lunarlander"]["space"]
    #: Fixed ``gym.make`` keywords (``--env-arg KEY=VALUE`` strings), e.g. Taxi's map file.
    env_args: tuple[str, ...] = ()
    arms: tuple[str, ...] = ("dsage",)
    seeds: tuple[int, ...] = (100, 101, 102, 103, 104)
    #: The equal-episodes budget: every run plays at least this many episodes.
    episodes: int = 300
    #: Records of the ``dsage`` runs: each other run goes on until it has spent the CPU seconds of that seed's.
    cpu_from: Path | None = None
    #: Or a fixed CPU budget (s) every run goes on to (the table flags a run that ended before its seed's dsage).
    cpu: float | None = None
    #: Episodes a run plays at least (default: ``episodes``); 1 with a CPU budget: the equal-CPU reading alone, for an
    #: arm too slow to reach the episode budget here (the table marks its equal-episodes counts as short).
    min_episodes: int | None = None
    out: Path = Path("peer_runs.jsonl")
    #: A tag kept in each record (``tuning``, ``fresh``), so tuning runs and published runs never mix.
    tag: str = "fresh"
    #: The table's row for these runs (default: the arm), e.g. a DSAGE setting beside the default; the equal-CPU
    #: budgets come from the rows labelled ``dsage``.
    label: str = ""
    # mdpfuzz (its protocol: 1000 of 5000 episodes to initialise the pool, k = 10, tau = gamma = 0.01, a Gaussian
    # mutation of the task's intensity, 5 N for LunarLander's force; local sensitivity).
    mdpfuzz_init_share: float = 0.2
    mdpfuzz_intensity: float = 5.0
    #: ``gaussian``: N(input, intensity) on every coordinate; ``one_coordinate`` (integer levels, their Taxi
    #: executor's): one coordinate redrawn among its other values, each weighted by how near it is.
    mdpfuzz_mutation: str = "gaussian"
    mdpfuzz_k: int = 10
    mdpfuzz_tau: float = 0.01
    mdpfuzz_gamma: float = 0.01
    # Tune's OptunaSearch (TPE)
    tpe_startup: int = 10
    # Indago's idea
    indago_warmup: int = 60
    indago_picks: int = 10
    indago_population: int = 200
    indago_generations: int = 10
    indago_sigma: float = 0.1
    #: Overrides of the DSAGE arms' config (dotted keys, as ``--set``).
    ours_set: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------- counting


class BudgetSpent(Exception):
    """The ledger's episode and CPU budgets are both spent: the arm stops."""


def cpu_seconds() -> float:
    """CPU seconds of this process (all threads) and of its waited-for children."""
    times = os.times()
    return time.process_time() + times.children_user + times.children_system


def cell_of(measures: np.ndarray, *, ranges: Sequence[Sequence[float]], dims: Sequence[int]) -> tuple[int, ...]:
    """The grid cell of a measure vector: ``dims`` equal cells over each range, values outside in the edge cells."""
    low, high = np.asarray(ranges, dtype=float).T
    index = np.floor((np.asarray(measures, dtype=float) - low) / (high - low) * np.asarray(dims))
    return tuple(int(i) for i in np.clip(index, 0, np.asarray(dims) - 1))


@dataclass(frozen=True)
class Counts:
    """What an arm found within a budget."""

    faults: int
    #: Failing levels distinct at 1% of each parameter's range (:data:`LEVEL_BINS` bins a parameter): near-copies of
    #: one fault, a step of a few newtons apart, count once.
    separate_faults: int
    fault_cells: int
    #: Cells holding any level played (the behaviour coverage the QD paper reports beside the faults).
    cells: int
    #: The lowest return of an episode (what Tune's searcher minimises).
    lowest_return: float
    episodes: int
    cpu: float


#: Bins per parameter over the box [-1, 1] for :attr:`Counts.separate_faults`: 1% of each parameter's range.
LEVEL_BINS = 100


def count(trace: Sequence[dict[str, Any]], *, episodes: int | None = None, cpu: float | None = None) -> Counts:
    """The counts over the first ``episodes`` episodes of a trace, or over those that ended within ``cpu`` seconds.

    A fault is a distinct failing level (its parameter vector as float32), a fault cell a distinct cell holding one.
    Separate faults are distinct at 1% of each parameter's range: on a continuous box two float vectors always
    differ, so a search replaying near-copies of one fault would count each copy as a fault.
    """
    if (episodes is None) == (cpu is None):
        raise ValueError("give episodes or cpu")
    rows = list(trace[:episodes]) if episodes is not None else [row for row in trace if row["cpu"] <= cpu]
    failing = [row for row in rows if row["fault"]]
    levels = {np.asarray(row["level"], dtype=np.float32).tobytes() for row in failing}
    bins = {cell_of(row["level"], ranges=[(-1.0, 1.0)] * len(row["level"]), dims=[LEVEL_BINS] * len(row["level"]))
            for row in failing}
    cells = {tuple(row["cell"]) for row in failing}
    return Counts(faults=len(levels), separate_faults=len(bins), fault_cells=len(cells),
                  cells=len({tuple(row["cell"]) for row in rows}),
                  lowest_return=min((row["return"] for row in rows), default=float("nan")), episodes=len(rows),
                  cpu=rows[-1]["cpu"] if rows else 0.0)


class Ledger:
    """Plays levels through a domain and records each episode: its level, fault, grid cell and CPU clock.

    Args:
        domain: The gym domain (one deterministic episode per evaluation).
        episodes: Stop (raise :class:`BudgetSpent`) once this many episodes are played ...
        cpu: ... and this many CPU seconds spent since the ledger was made (None: episodes alone).
        clock: The CPU clock (tests pass a fake).
    """

    def __init__(self, *, domain: Any, episodes: int, cpu: float | None = None,
                 clock: Callable[[], float] = cpu_seconds) -> None:
        self.domain = domain
        self.episodes = episodes
        self.cpu = cpu
        self.clock = clock
        self.started = clock()
        self.trace: list[dict[str, Any]] = []

    @property
    def spent(self) -> bool:
        if len(self.trace) < self.episodes:
            return False
        return self.cpu is None or self.clock() - self.started >= self.cpu

    def canonical(self, level: np.ndarray) -> np.ndarray:
        """``level`` clipped to the box, each integer or choice coordinate moved to its value's own point, so that
        the points of one level are one level (a fault is a distinct level)."""
        level = np.clip(np.asarray(level, dtype=np.float32), -1.0, 1.0)
        for i, parameter in enumerate(self.domain.space.params):
            if parameter.kind != "float":
                level[i] = parameter.unit(parameter.value(float(level[i])))
        return level

    def play(self, level: np.ndarray, seed: int = 0) -> Any:
        """Plays ``level`` (a point of the domain's box [-1, 1]^P) and returns its evaluation result."""
        if self.spent:
            raise BudgetSpent
        level = self.canonical(level)
        result = self.domain.evaluate(level, seed)
        fault = bool(result.objective >= 0.5)  # one deterministic episode: 1.0 is a fault, 0.0 none
        self.trace.append({"level": level.tolist(), "fault": fault, "return": float(result.info["mean_return"]),
                           "cell": list(cell_of(result.measures, ranges=self.domain.measure_ranges,
                                                dims=self.domain.archive_dims)),
                           "cpu": self.clock() - self.started})
        return result


class LedgerDomain:
    """The domain as the runner sees it, every evaluation played through the ledger (the rest delegated)."""

    def __init__(self, domain: Any, ledger: Ledger) -> None:
        self._inner = domain
        self._ledger = ledger

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def evaluate(self, solution: np.ndarray, seed: int, *, episodes: int | None = None) -> Any:
        return self._ledger.play(solution, seed)


# ------------------------------------------------------------------------------------------------ arms


def run_ours(arm: str, ledger: Ledger, *, seed: int, config: Config) -> None:
    """DSAGE or one of the gym domain's variants, the ``demo`` preset, stepped until the ledger is spent (a step's
    batch may overshoot; the counts read the trace's prefix). ``dsage`` stops at the episode budget unless the ledger
    has a CPU budget (a DSAGE setting measured beside the default, ``--label``), like every other arm."""
    from dsage_ray.audit.collection import audit_config
    from dsage_ray.core.runner import DSAGE, EvaluationsFailed

    run_config = audit_config(domain="gym", agent=config.agent, preset="demo", variant=arm, seed=seed,
                              budget=10 ** 6,
                              overrides={"gym.space": config.space, "gym.env_args": config.env_args, **config.ours_set})
    if arm == "dsage" and ledger.cpu is None:
        run_config = run_config.replace(budget=config.episodes)
    run = DSAGE(config=run_config, domain=LedgerDomain(ledger.domain, ledger))
    try:
        while not ledger.spent and not run.done:
            run.step()
    except EvaluationsFailed:
        if not ledger.spent:  # a batch played after the budget fails as a whole: the arm is done
            raise
    choice = getattr(run.proposer, "choice", None)  # search = "auto": what it chose, and on which numbers
    if choice is not None:
        print(choice.reason, flush=True)


def redraw_one_coordinate(level: np.ndarray, rng: np.random.Generator, *, low: np.ndarray,
                          high: np.ndarray) -> np.ndarray:
    """Their Taxi executor's mutation, over integer levels: one coordinate, drawn uniformly, takes another of its
    values, each with weight (its farthest value's distance) - (its distance), so nearer values are likelier."""
    mutant = np.array(level, dtype=float)
    i = int(rng.integers(len(mutant)))
    values = np.arange(low[i], high[i] + 1)
    distance = np.abs(values - mutant[i])
    weights = np.where(distance == 0, 0.0, distance.max() - distance)
    if weights.sum() == 0:  # two values: the other one
        weights = (distance > 0).astype(float)
    mutant[i] = rng.choice(values, p=weights / weights.sum())
    return mutant


def run_mdpfuzz(arm: str, ledger: Ledger, *, seed: int, config: Config) -> None:
    """mdpfuzz's random testing (``rt``), ``Fuzzer`` (no coverage) or ``MDPFuzz``, as its LunarLander scripts call
    them, through an executor whose episodes are the ledger's (inputs in N, as the peers' executor draws them)."""
    from mdpfuzz.executor import Executor
    from mdpfuzz.mdpfuzz import Fuzzer

    # The peers' executors draw and mutate inputs in the parameters' own units (N, m, rad); a level is the input
    # mapped onto the domain's box [-1, 1]^P.
    low = np.array([p.low for p in ledger.domain.space.params], dtype=float)
    high = np.array([p.high for p in ledger.domain.space.params], dtype=float)
    integers = np.array([p.kind != "float" for p in ledger.domain.space.params])

    def draw(rng: np.random.Generator, size: Any) -> np.ndarray:
        """Uniform inputs; integer coordinates uniform over their values (their Taxi executor's ``integers``)."""
        x = rng.uniform(low, high, size=size)
        return np.where(integers, np.floor(rng.uniform(low, high + 1, size=size)).clip(low, high), x)

    class LedgerExecutor(Executor):
        def generate_input(self, rng):
            return draw(rng, None)

        def generate_inputs(self, rng, n=1):
            return draw(rng, None) if n == 1 else draw(rng, (n, len(low)))

        def mutate(self, input, rng, **kwargs):
            if config.mdpfuzz_mutation == "one_coordinate":
                return redraw_one_coordinate(np.asarray(input), rng, low=low, high=high)
            return np.clip(rng.normal(input, config.mdpfuzz_intensity), low, high)

        def load_policy(self, **kwargs):
            return None

        def execute_policy(self, input, policy):
            tic = time.time()
            result = ledger.play(2.0 * (np.asarray(input) - low) / (high - low) - 1.0)
            observations = ledger.domain.last_observations
            return result.info["mean_return"], bool(ledger.trace[-1]["fault"]), observations, time.time() - tic

    fuzzer = Fuzzer(random_seed=seed, k=config.mdpfuzz_k, tau=config.mdpfuzz_tau, gamma=config.mdpfuzz_gamma,
                    executor=LedgerExecutor(sim_steps=ledger.domain.space.max_episode_steps or 1000,
                                                   env_seed=0))
    init = max(1, int(config.mdpfuzz_init_share * config.episodes))
    with tempfile.TemporaryDirectory() as folder:
        try:
            if arm == "rt":
                fuzzer.random_testing(n=10 ** 9, path=f"{folder}/rt", check_redundant_input=True)
            elif arm == "fuzzer":
                fuzzer.fuzzing_no_coverage(n=init, test_budget=10 ** 9, local_sensitivity=True)
            else:
                fuzzer.fuzzing(n=init, test_budget=10 ** 9, local_sensitivity=True)
        except BudgetSpent:
            pass
    # MDPFuzz's main loop catches every exception (and prints it), the budget's too: nothing else may have ended it.
    if not ledger.spent:
        raise RuntimeError(f"{arm} stopped before its budget was spent")


def run_tpe(ledger: Ledger, *, seed: int, config: Config) -> None:
    """Ray Tune's OptunaSearch (TPE) minimising the episode's return over the two forces."""
    import optuna
    from ray.tune.search.optuna import OptunaSearch

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    params = ledger.domain.space.params
    # An integer parameter is an integer distribution, as an Optuna user declares one (choices: their indices).
    space = {p.name: optuna.distributions.FloatDistribution(-1.0, 1.0) if p.kind == "float"
             else optuna.distributions.IntDistribution(int(p.low), int(p.high)) for p in params}
    searcher = OptunaSearch(space=space, metric="episode_return", mode="min",
                            sampler=optuna.samplers.TPESampler(seed=seed, n_startup_trials=config.tpe_startup))
    trial = 0
    while not ledger.spent:
        suggested = searcher.suggest(str(trial))
        result = ledger.play(np.array([suggested[p.name] if p.kind == "float"
                                       else 2.0 * (suggested[p.name] - p.low) / (p.high - p.low) - 1.0
                                       for p in params]))
        searcher.on_trial_complete(str(trial), {"episode_return": result.info["mean_return"]})
        trial += 1


def run_indago(ledger: Ledger, *, seed: int, config: Config) -> None:
    """Indago's idea: a random-forest pass/fail classifier of the levels played so far is the fitness of a genetic
    algorithm (tournament, blend crossover, Gaussian mutation) over the box; its top unplayed picks are played."""
    from sklearn.ensemble import RandomForestClassifier

    rng = np.random.default_rng(seed)
    dim = ledger.domain.solution_dim
    while not ledger.spent:
        levels = np.array([row["level"] for row in ledger.trace]).reshape(-1, dim)
        labels = np.array([row["fault"] for row in ledger.trace], dtype=bool)
        if len(levels) < config.indago_warmup or labels.all() or not labels.any():
            for level in rng.uniform(-1, 1, size=(config.indago_picks, dim)):
                ledger.play(level)
            continue
        model = RandomForestClassifier(n_estimators=50, random_state=int(rng.integers(2 ** 31))).fit(levels, labels)
        fitness = lambda x: model.predict_proba(x)[:, 1]  # noqa: E731
        # The population starts from the failing levels and random ones.
        population = np.concatenate([levels[labels], rng.uniform(-1, 1, size=(config.indago_population, dim))])
        population = population[rng.permutation(len(population))[: config.indago_population]]
        for _ in range(config.indago_generations):
            score = fitness(population)
            a, b = rng.integers(len(population), size=(2, len(population)))
            parents = np.where((score[a] >= score[b])[:, None], population[a], population[b])
            mates = parents[rng.permutation(len(parents))]
            weight = rng.uniform(-0.25, 1.25, size=parents.shape)
            children = np.clip(weight * parents + (1 - weight) * mates
                               + rng.normal(0, config.indago_sigma, size=parents.shape), -1, 1)
            pool = np.concatenate([population, children])
            population = pool[np.argsort(-fitness(pool), kind="stable")[: config.indago_population]]
        played = {np.asarray(level, dtype=np.float32).tobytes() for level in levels}
        picks = [x for x in population if ledger.canonical(x).tobytes() not in played][: config.indago_picks]
        for level in picks or rng.uniform(-1, 1, size=(config.indago_picks, dim)):
            ledger.play(level)


def run_arm(arm: str, ledger: Ledger, *, seed: int, config: Config) -> None:
    """Plays ``arm`` through ``ledger`` until it is spent."""
    try:
        if arm in OURS:
            run_ours(arm, ledger, seed=seed, config=config)
        elif arm in ("rt", "fuzzer", "mdpfuzz"):
            run_mdpfuzz(arm, ledger, seed=seed, config=config)
        elif arm == "tpe":
            run_tpe(ledger, seed=seed, config=config)
        elif arm == "indago":
            run_indago(ledger, seed=seed, config=config)
        else:
            raise SystemExit(f"unknown arm {arm!r}: one of {', '.join(OURS + PEERS)}")
    except BudgetSpent:
        pass  # an arm that plays a batch stops within it


# ----------------------------------------------------------------------------------------------- domain


def make_domain(config: Config) -> Any:
    """The task's gym domain, its agent loaded (before any clock starts), recording each episode's observations
    (MDPFuzz's coverage model reads them)."""
    from dsage_ray.audit.collection import audit_config
    from dsage_ray.domains import domain_class

    run_config = audit_config(domain="gym", agent=config.agent, preset="demo",
                              overrides={"gym.space": config.space, "gym.env_args": config.env_args})
    base = domain_class(run_config.domain)

    class Recorder:
        """The agent, recording the observations it is given (one episode at a time)."""

        def __init__(self, agent: Any, into: list) -> None:
            self._agent, self._into = agent, into

        def __getattr__(self, name: str) -> Any:
            return getattr(self._agent, name)

        def act(self, batch, state, rng):
            self._into.append(np.array(batch[0], dtype=np.float64))
            return self._agent.act(batch, state, rng)

    class RecordingDomain(base):
        def __init__(self, **kwargs: Any) -> None:
            super().__init__(**kwargs)
            self.observations: list[np.ndarray] = []
            self._recorder = None

        @property
        def agent(self):
            if self._recorder is None:
                self._recorder = Recorder(super().agent, self.observations)
            return self._recorder

        def evaluate(self, solution, seed, *, episodes=None):
            self.observations.clear()
            return super().evaluate(solution, seed, episodes=episodes)

        @property
        def last_observations(self) -> np.ndarray:
            """The episode's observations, one row each (a Discrete state is a row of one)."""
            return np.array(self.observations).reshape(len(self.observations), -1)

    domain = RecordingDomain(config=run_config.domain_config)
    domain.evaluate(np.zeros(domain.solution_dim, dtype=np.float32), 0)  # loads the agent, warms the caches
    return domain


# ----------------------------------------------------------------------------------------------- tables


def load_records(paths: Sequence[Path], *, tag: str | None = None) -> list[dict[str, Any]]:
    def text(path: Path) -> str:  # the committed records are gzipped
        return gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()

    records = [json.loads(line) for path in paths for line in text(path).splitlines() if line.strip()]
    return [r for r in records if tag is None or r["tag"] == tag]


def reference_cpu(records: Sequence[dict[str, Any]], *, reference: str = "dsage") -> dict[int, float]:
    """The CPU seconds each seed's run of the ``reference`` row spent (its whole run)."""
    return {r["seed"]: r["trace"][-1]["cpu"] for r in records if row_of(r) == reference}


def row_of(record: dict[str, Any]) -> str:
    """The table row of a record: its label, else its arm."""
    return record.get("label") or record["arm"]


def table(records: Sequence[dict[str, Any]], *, cpu_budget: float | None = None, reference: str = "dsage") -> str:
    """The headline table: each arm's counts at equal episodes and at equal CPU time, mean ± s.e. over seeds.

    Equal CPU time is each seed's CPU seconds of the ``reference`` row (the runs that set the other arms' budgets),
    or ``cpu_budget`` seconds for every run (the tuning runs, each run to a fixed CPU budget). The records are read
    at the budget they were run to, never at a smaller one: MDPFuzz's arms size their random start from it.
    """
    budgets = {r["episodes"] for r in records}
    if len(budgets) != 1:
        raise SystemExit(f"records of different episode budgets: {sorted(budgets)}")
    (budget,) = budgets
    cpu = (reference_cpu(records, reference=reference) if cpu_budget is None
           else {r["seed"]: cpu_budget for r in records})
    by_arm: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for record in records:
        by_arm[row_of(record)].append(record)
    source = "dsage CPU seconds" if reference == "dsage" else f"CPU seconds of {reference}"
    equal_cpu = (f"{cpu_budget:g} CPU s a run" if cpu_budget is not None else
                 f"each seed's {source} ({format_mean_se(*mean_se(cpu.values()), '.1f') if cpu else 'none'} s)")
    lines = [f"episode budget {budget}; equal CPU: {equal_cpu}; mean ± s.e. over seeds",
             "| search | seeds | faults | faults at 1% | fault cells | cells covered | lowest return | CPU s "
             "| faults @ CPU | faults at 1% @ CPU | fault cells @ CPU | cells @ CPU | episodes @ CPU |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for arm in [a for a in OURS if a in by_arm] + sorted(set(by_arm) - set(OURS + PEERS)) + \
            [a for a in PEERS if a in by_arm]:
        runs = sorted(by_arm[arm], key=lambda r: r["seed"])
        at = [count(r["trace"], episodes=budget) for r in runs]
        cells = [arm, ",".join(str(r["seed"]) for r in runs)]
        cells += [format_mean_se(*mean_se(getattr(c, name) for c in at), spec)
                  for name, spec in (("faults", ".1f"), ("separate_faults", ".1f"), ("fault_cells", ".1f"),
                                     ("cells", ".1f"), ("lowest_return", ".1f"), ("cpu", ".0f"))]
        short = [c.episodes for c in at if c.episodes < budget]
        cells[2] += f" (short: {min(short)}-{max(short)} episodes)" if short else ""
        if all(r["seed"] in cpu for r in runs):
            at = [count(r["trace"], cpu=cpu[r["seed"]]) for r in runs]
            short = sum(r["trace"][-1]["cpu"] < cpu[r["seed"]] for r in runs)
            cells += [format_mean_se(*mean_se(getattr(c, name) for c in at), spec)
                      for name, spec in (("faults", ".1f"), ("separate_faults", ".1f"), ("fault_cells", ".1f"),
                                         ("cells", ".1f"), ("episodes", ".0f"))]
            cells[-1] += f" ({short} short)" if short else ""
        else:
            cells += ["-"] * 5
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------- main


def parse_args(argv: list[str] | None = None) -> tuple[Config, list[Path] | None, str]:
    """The invocation's config, the record files ``--table`` prints (or None) and the table's reference row."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    defaults = Config()
    parser.add_argument("--arms", nargs="+", default=list(defaults.arms), choices=OURS + PEERS)
    parser.add_argument("--seeds", nargs="+", type=int, default=list(defaults.seeds))
    parser.add_argument("--table", nargs="+", type=Path,
                        help="print the table of these record files and stop (with --cpu: equal CPU is that budget)")
    parser.add_argument("--reference", default="dsage",
                        help="with --table: the row whose CPU seconds are each seed's equal-CPU budget")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a Config field (mdpfuzz_intensity=20) or ours.KEY=VALUE for the DSAGE arms' config")
    parser.add_argument("--task", choices=sorted(TASKS), default=defaults.task,
                        help="the peers' task: its space, agent and mutation intensity (each overridable)")
    for name in ("agent", "space", "episodes", "cpu_from", "cpu", "min_episodes", "out", "tag", "label"):
        kind = {"cpu_from": Path, "cpu": float, "min_episodes": int}.get(name) or type(getattr(defaults, name))
        parser.add_argument(f"--{name.replace('_', '-')}", type=kind,
                            default=None if name in ("agent", "space") else getattr(defaults, name))
    args = parser.parse_args(argv)
    task = TASKS[args.task]
    config = Config(task=args.task, agent=args.agent or task["agent"], space=args.space or task["space"],
                    env_args=tuple(task.get("env_args", ())),
                    mdpfuzz_intensity=task.get("mdpfuzz_intensity", Config.mdpfuzz_intensity),
                    mdpfuzz_mutation=task.get("mdpfuzz_mutation", Config.mdpfuzz_mutation), arms=tuple(args.arms), seeds=tuple(args.seeds),
                    episodes=args.episodes, cpu_from=args.cpu_from, cpu=args.cpu,
                    min_episodes=args.min_episodes, out=args.out, tag=args.tag, label=args.label)
    types = {f.name: f.type for f in dataclasses.fields(Config)}
    for item in args.set:
        key, _, value = item.partition("=")
        if key.startswith("ours."):
            config.ours_set[key[len("ours."):]] = json.loads(value)
        elif key in types and isinstance(getattr(config, key), (int, float)):
            setattr(config, key, type(getattr(config, key))(value))
        else:
            parser.error(f"--set {item}: not a numeric Config field nor ours.KEY")
    return config, args.table, args.reference


def main(argv: list[str] | None = None) -> None:
    config, tables, reference_row = parse_args(argv)
    if tables:
        print(table(load_records(tables, tag=None), cpu_budget=config.cpu, reference=reference_row))
        return
    cpu = reference_cpu(load_records([config.cpu_from])) if config.cpu_from else {}
    import torch

    # Every arm plays on one torch thread, as the runner's steps do (config torch_threads = 1): a second thread
    # spinning beside a small per-step batch would bill CPU seconds to the arms that play outside the runner.
    torch.set_num_threads(1)
    domain = make_domain(config)
    # Each arm once on a throwaway ledger first, so that no seed's CPU seconds hold the arm's first imports and
    # first calls (on Taxi, where an episode costs a millisecond, they were most of DSAGE's first seed).
    for arm in config.arms:
        run_arm(arm, Ledger(domain=domain, episodes=WARM_UP_EPISODES), seed=0, config=config)
    # Arm by arm, so that every arm finished has all its seeds.
    for arm in config.arms:
        for seed in config.seeds:
            # The default's dsage runs set the equal-CPU budgets; a labelled DSAGE setting runs to them, as the
            # peers do.
            reference = arm == "dsage" and config.label in ("", "dsage")
            budget = None if reference else cpu.get(seed, config.cpu)
            if config.cpu_from and not reference and budget is None:
                raise SystemExit(f"{config.cpu_from} holds no dsage run of seed {seed}")
            ledger = Ledger(domain=domain, episodes=config.min_episodes or config.episodes, cpu=budget)
            run_arm(arm, ledger, seed=seed, config=config)
            record = {"arm": arm, "label": config.label or arm, "seed": seed, "tag": config.tag,
                      "episodes": config.episodes, "cpu_budget": budget,
                      "config": {k: v for k, v in dataclasses.asdict(config).items()
                                 if k not in ("arms", "seeds", "out", "cpu_from")}, "trace": ledger.trace}
            with config.out.open("a") as out:
                out.write(json.dumps(record, default=str) + "\n")
            at = count(ledger.trace, episodes=config.episodes)
            print(f"{arm} seed {seed}: {at.faults} faults ({at.separate_faults} at 1%) in {at.fault_cells} cells in "
                  f"{at.episodes} episodes "
                  f"({at.cpu:.1f} CPU s); the run: {len(ledger.trace)} episodes, {ledger.trace[-1]['cpu']:.1f} CPU s",
                  flush=True)


if __name__ == "__main__":
    main()
