"""The config's schema: the sections of a run config (dataclasses whose fields carry what ``dsage-ray config`` and
docs/CONFIG.md say about them, :func:`key`) and the closed sets of names some keys pick from."""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

from dsage_ray.errors import InputError


class ConfigError(InputError):
    """An invalid config; the message names the offending key."""


# The closed sets of names a config value picks from. Each is the key set of the table that
# implements the names (checked equal in tests/test_config.py); the tables live with their code,
# which imports pyribs or the simulators, so config validation can stay import-free.

#: Keys of :data:`dsage_ray.qd.optimizer.EMITTERS`.
EmitterName = Literal["map_elites", "cma_me", "random", "gaussian", "halton", "cross_entropy"]
#: The emitters with a mutation, the keys of :data:`dsage_ray.qd.mutants.MUTATIONS` (``selection.elite_mutants``).
MutatingEmitter = Literal["map_elites", "cma_me", "gaussian", "halton", "cross_entropy"]
#: Keys of :data:`dsage_ray.qd.selection.SELECTION_METHODS`.
SelectionMethod = Literal["downsample", "random", "full"]
#: Surrogate kinds: ancillary occupancy (``two_stage``), without it (``one_stage``), none (plain QD).
SurrogateKind = Literal["two_stage", "one_stage", "none"]
#: Surrogate prediction arithmetic.
Precision = Literal["auto", "fp32", "bf16"]
#: Where ``selection.elite_mutants`` draw their parents: ``elites``, among the ground-truth archive's best elites
#: (one level a cell); ``evaluated``, among every level evaluated as good as those (a region dense with good
#: levels, such as a run of faults, parents more mutants).
MutantParents = Literal["elites", "evaluated"]
#: ``fixed``: the variant runs as set; ``auto``: DSAGE, then the domain's direct search if the surrogate costs more
#: than it buys (:mod:`dsage_ray.core.auto_search`).
SearchMode = Literal["fixed", "auto"]


def key(default: Any, *, status: str, values: str = "", note: str = "") -> Any:
    """A config field with what ``dsage-ray config`` and docs/CONFIG.md say about it.

    Args:
        default: The default value (a tuple stays immutable; no factory needed).
        status: ``paper`` (the paper's algorithm or value), ``tool`` (how the tool runs, not the search),
            ``default-on`` (beyond the paper, on in the presets or audits that ``note`` names), ``opt-in`` (beyond the
            paper, measured to help where ``note`` says, not yet on in a preset) or ``experimental`` (beyond the paper
            and off; ``note`` gives its measured effect).
        values: The values it takes, where its type does not say (``>= 1``, ``(0, 1]``).
        note: One line: what it does, and where measured, what it did.
    """
    return dataclasses.field(default=default, metadata={"status": status, "values": values, "note": note})


@dataclasses.dataclass
class SurrogateConfig:
    """The deep surrogate model (SPEC: the surrogate)."""

    kind: SurrogateKind = key("two_stage", status="paper",
                              note="two_stage predicts the agent's occupancy first (ancillary data); none: plain QD")
    epochs: int = key(200, status="paper", values=">= 1", note="epochs of each training on the recent window")
    batch_size: int = key(64, status="paper", values=">= 1", note="Adam's minibatch size in each training")
    lr: float = key(1e-3, status="paper", values="> 0", note="Adam's learning rate")
    occupancy_weight: float = key(10.0, status="paper", values=">= 0",
                                  note="weight of the occupancy loss in the two-stage model's loss")
    train_window: int = key(20_000, status="paper", values=">= 1", note="the most recent evaluations trained on")
    #: Width of the networks (the first convolution of both predictors); 64 is the paper's. The residual
    #: blocks' cost grows as its square (benchmarks/bench_surrogate.py prints FLOPs and predictions/s).
    channels: int = key(64, status="paper", values=">= 1",
                        note="network width; 16 cut the surrogate's share of a Maze cpu run from ≈50% to 17% for "
                             "5% less QD-score (docs/DECISIONS.md)")
    #: Prediction arithmetic: ``fp32``, ``bf16`` (the two-stage model's residual blocks, most of its work,
    #: under bf16 autocast) or ``auto`` (bf16 on CUDA and on CPUs with native bf16, else fp32). Training is
    #: always fp32. ``auto`` resolves per machine, as ``device`` does.
    precision: Precision = key("auto", status="default-on",
                               note="prediction arithmetic; auto: bf16 where the CPU or GPU has it, else fp32")
    device: str = key("auto", status="tool", values="auto, cpu, cuda, cuda:N",
                      note="where the surrogate trains and predicts; auto: CUDA when available")
    #: Warm start (beyond the paper): a file of ``dsage-ray surrogate pretrain``, or an earlier surrogate
    #: run, audit or trial folder (or its ``checkpoint.dsage``). Its weights start this run's surrogate and
    #: the first outer iteration exploits them instead of evaluating ``n_rand`` random levels
    #: (:mod:`dsage_ray.core.warm_start`). Empty: a cold start (the paper). Made absolute when the
    #: config is built (Tune trials run in their own folder).
    init: str = key("", status="default-on", values="PATH or empty",
                    note="warm start from a pretrained surrogate or an earlier run (audit-series uses it)")
    #: Take the measures (and objective) that are functions of the level alone from the level itself, not from
    #: the network (Maze: ``num_walls``, ``optimal_path_length`` and the ``validity`` objective; Mario: ``sky_tiles``),
    #: through the domain's ``level_values``. The network still trains on them. Off (the paper): everything is
    #: predicted, so a pick can land a few wall counts away from the cell the inner loop chose it for.
    exact_level_values: bool = key(False, status="default-on",
                                   note="take measures a level fixes by itself from the level "
                                        "(audits; docs/DECISIONS.md)")
    #: Name of a measure that equals the sum of the occupancy grid (Maze: ``mean_path_length``, since
    #: the grid counts the agent's steps); a two-stage surrogate then predicts it as the sum of its
    #: predicted occupancy instead of with its own head. Empty (the paper): every measure has a head.
    occupancy_sum_measure: str = key("", status="default-on", values="a measure name or empty",
                                     note="predict this measure as the predicted occupancy's sum (Maze cpu preset: "
                                          "QD-score 1,597 ± 17.5 against 1,423.7 ± 24.7)")
    #: Name of a measure the domain has a parameter-free prior for (Maze: ``mean_path_length``, the expected
    #: steps of a uniform random walker from the start to the goal). Its prediction is then the mean of the
    #: network's and the prior's, the prior mapped to the measure by a least-squares line on
    #: ``log(1 + prior)`` fitted to the training window after each training. Empty (the paper): the network alone.
    prior_measure: str = key("", status="default-on", values="a measure name or empty",
                             note="blend this measure's prediction with the domain's prior (Maze cpu preset: "
                                  "30% lower error on the picks, QD-score level)")


@dataclasses.dataclass
class QDConfig:
    """The QD optimizer used on the surrogate (inner loop) or directly (baselines)."""

    #: ``map_elites`` (discrete bitmaps), ``cma_me`` (continuous latents), ``random`` (DR), or for continuous
    #: vectors in a box (the domain's ``solution_bounds``, else [-1, 1]): ``gaussian`` (MAP-Elites with Gaussian
    #: mutation of ``sigma0``), ``halton`` (quasi-random samples) or ``cross_entropy`` (a cross-entropy falsifier).
    emitter: EmitterName = key("map_elites", status="paper", note="the QD search, in the inner loop or alone")
    num_emitters: int = key(5, status="paper", values=">= 1", note="emitters asking in parallel each step")
    batch_size: int = key(30, status="paper", values=">= 1", note="solutions each emitter asks for per step")
    #: MAP-Elites: cells mutated per offspring.
    mutation_cells: int = key(10, status="paper", values=">= 1", note="MAP-Elites: tiles changed per mutation")
    #: CMA-ME's initial step size; ``gaussian``'s mutation std.
    sigma0: float = key(0.2, status="paper", values="> 0", note="CMA-ME's initial step; the Gaussian mutation's std")
    #: Inner-loop iterations (N_exploit) per outer iteration.
    exploit_iterations: int = key(10_000, status="paper", values=">= 1", note="inner-loop steps per outer iteration")


@dataclasses.dataclass
class SelectionConfig:
    """Which surrogate elites get a real evaluation."""

    method: SelectionMethod = key("downsample", status="paper", note="how picks are taken from the surrogate archive")
    #: Downsampling block in archive cells per measure.
    block: tuple[int, ...] = key((8, 6), status="paper", values="one size per measure",
                                 note="downsampling block, in archive cells per measure")
    #: ``random``: how many elites to pick.
    count: int = key(432, status="paper", values=">= 1", note="random selection: how many elites")
    #: Each outer iteration after the first, also evaluate this many mutants of the ground-truth archive's best
    #: elites (``experimental.elite_share``), beside the surrogate's picks (not in the paper;
    #: :mod:`dsage_ray.qd.mutants`). The mutation is MAP-Elites' (``qd.mutation_cells``) for bitmaps, Gaussian
    #: (``qd.sigma0``, clipped to the domain's ``solution_bounds``) for the continuous emitters' vectors. An audit's
    #: never-solved levels are the best elites, and a mutant of one is often never solved too, which the surrogate
    #: cannot predict within a cell. 0 (the paper): only the surrogate's picks.
    elite_mutants: int = key(0, status="default-on", values=">= 0",
                             note="mutants of the best elites beside the picks (audits; docs/DECISIONS.md)")
    #: Before the real evaluation, screen the picks and more candidates with this many episodes each (the domain's
    #: ``screen``: Maze only) and evaluate, up to the selection's size, those whose screened result adds to the
    #: ground truth (not in the paper; :mod:`dsage_ray.qd.screen`). MAP-Elites (``qd.emitter = "map_elites"``
    #: without a surrogate) screens mutants of its elites instead, once its random start-up is over. 0 (the
    #: paper): evaluate the picks as chosen.
    screen_episodes: int = key(0, status="opt-in", values=">= 0",
                               note="play candidates this many episodes before evaluating (Maze; docs/DECISIONS.md)")
    #: With ``screen_episodes``: keep the screened candidates expected to add most to the ground truth per expected
    #: cost, judged by the screen's errors on recently evaluated levels and the domain's cost model
    #: (``evaluation_cost`` of its config section: Maze's grows with the mean path length), instead of those whose
    #: screened cell alone would add, in the order screened (not in the paper; :func:`dsage_ray.qd.screen.keep_screened`).
    screen_gain: bool = key(False, status="opt-in",
                            note="rank screened candidates by expected gain per cost (on in the Maze cpu preset: "
                                 "1.15× MAP-Elites at equal CPU time, docs/DECISIONS.md)")


@dataclasses.dataclass
class RayConfig:
    """How a run uses Ray (ignored by the in-process runner): simulator actors and the trial's resources."""

    num_workers: int = key(2, status="tool", values=">= 0",
                           note="simulator actors in the pool (0: evaluate in the trial process)")
    cpus_per_worker: float = key(0.5, status="tool", values="> 0", note="logical CPUs each simulator actor reserves")
    trial_cpus: float = key(1.0, status="tool", values="> 0",
                            note="logical CPUs the trial reserves (surrogate training and the inner loop)")


@dataclasses.dataclass
class ExperimentalConfig:
    """Beyond the paper and off by default: each was measured, and none is a clear win where it was tried.

    ``dsage-ray config --experimental`` lists them with what they did; docs/CONFIG.md links the measurements.
    """

    #: Random valid levels evaluated once, outside the budget, to score the surrogate on levels it
    #: never trains on (``holdout_*`` metrics each outer iteration); 0 turns it off.
    holdout_levels: int = key(0, status="experimental", values=">= 0",
                              note="levels held out to score the surrogate each iteration; a diagnostic, "
                                   "+5% evaluations at 100 (surrogate_accuracy)")
    #: With ``surrogate.init``: its dataset becomes the oldest part of this run's dataset, so it weighs in the first
    #: trainings and leaves the ``train_window`` as this run's evaluations arrive. Off: weights only.
    init_prior: bool = key(True, status="experimental",
                           note="with surrogate.init, also train on the source's levels; every measured warm start had it on")
    #: ``selection.elite_mutants``: the parents are drawn uniformly among this share of the ground-truth elites,
    #: the best by objective (ties with the last one included).
    elite_share: float = key(0.05, status="experimental", values="(0, 1]",
                             note="share of best elites the mutants' parents come from (tuned on one seed)")
    #: ``selection.elite_mutants`` of continuous vectors: their Gaussian step (0: ``qd.sigma0``, the inner loop's).
    mutant_sigma: float = key(0.0, status="experimental", values=">= 0 (0: qd.sigma0)",
                              note="the elite mutants' Gaussian step (0: qd.sigma0); 0.01 for gym [fault] spaces")
    #: ``selection.elite_mutants``: their parents, :data:`MutantParents`.
    mutant_parents: MutantParents = key("elites", status="experimental", values="elites or evaluated",
                                        note="the elite mutants' parents: the best elites, or every level "
                                             "evaluated as good (more faults, fewer LunarLander fault cells)")
    #: ``selection.screen_episodes``: candidates screened per pick (the picks, then other elites predicted to add),
    #: or per level of a MAP-Elites batch.
    screen_pool: float = key(4.0, status="experimental", values=">= 1",
                             note="candidates screened per pick; 3 and 6 level with 4 (docs/DECISIONS.md)")
    #: ``selection.screen_episodes``: the agent's arithmetic in the screen. ``fp32``: the agent as it is
    #: evaluated; ``bf16``: its matrix products in bf16, where the agent has such a copy
    #: (``Agent.reduced_precision``: the ``dcd`` agents); ``auto``: bf16 on a CPU with native bf16 arithmetic,
    #: else fp32. Evaluations always run the agent as it is.
    screen_precision: Precision = key("auto", status="experimental",
                                      note="the screen's agent arithmetic; bf16 cut the screen's share 6.7% → 4.8% "
                                           "(docs/DECISIONS.md)")
    #: ``selection.screen_gain``: how many of the latest evaluated levels' screen errors are kept.
    gain_window: int = key(1000, status="experimental", values=">= 1",
                           note="screen_gain: recent levels whose screen errors are kept (not tuned)")
    #: ``selection.screen_gain``: how many of them, nearest in screened measures, lend a candidate their errors.
    gain_neighbours: int = key(64, status="experimental", values=">= 1",
                               note="screen_gain: nearest levels lending a candidate their errors (not tuned)")
    #: Pick only surrogate elites predicted at least this good (where any is), each block's pick the one predicted
    #: to add most to the ground truth in its predicted cell (not in the paper); a negative floor keeps every elite,
    #: ranked by gain. A gym space that declares a ``[fault]`` takes 0.5, a predicted fault, unless the key is set
    #: (domains/gym/plugin.py's FAULT_SEARCH): on the peers' LunarLander task (tuning seed 1) it raised DSAGE's
    #: fault cells from 14 to 24 in 200 episodes (docs/results/peers). 0: off (every elite, uniformly per block,
    #: unless the cells are known).
    min_predicted: float = key(0.0, status="experimental", values="a number; 0: off",
                               note="pick only elites predicted at least this good; on (0.5) for gym [fault] spaces")
    #: Solutions per pool task; 0 picks ~8 chunks per actor per batch, 1 spreads uneven episodes best, larger
    #: amortises Ray's per-task round trip.
    chunk_size: int = key(0, status="experimental", values=">= 0 (0: automatic)",
                          note="solutions per Ray pool task (performance)")
