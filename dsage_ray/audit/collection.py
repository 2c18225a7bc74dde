"""Audits: a failure-eliciting DSAGE search, then a reproducible *collection* of the levels it found.

An audit is an ordinary DSAGE run (the runner, the Ray layer, the domain: nothing re-implemented) whose
objective rewards the agent doing badly on a valid level and whose measures describe the level. The
domain decides what "badly" means (the ``audit`` objectives of its registration: Maze ``failure_rate``,
``regret`` or ``regression`` against a reference agent; Mario ``incompletion``) and supplies the few hooks
the collection needs (:class:`~dsage_ray.types.AuditableDomain`: ``is_valid``, ``success_rate``,
``reference_numbers``, ``level_text``, ``render_evaluation``, ``reproduce_command``, ``entry_fields``,
``collection_fields``); everything else here is domain-generic.

**Seeds and reproducibility.** The search archive keeps each elite's solution and the numbers of the
evaluation that placed it, but not that evaluation's seed (the runner derives it from the run seed and the
evaluation's index, which the archive does not store). Rather than widen the archive, the collection
**re-evaluates every elite** with a fresh seed derived from the run seed and the elite's rank
(:func:`level_seed`) and records that seed next to the numbers. Every number in ``collection.json`` is
therefore the output of one evaluation of the level file with the recorded seed and episodes, and each
entry's ``reproduce`` command prints it again. A side effect is honest numbers: elites are the search's
*luckiest* evaluations, and a fresh evaluation removes that selection bias (the search's own value is kept
as ``search_objective``).

Collection folder (format ``dsage_ray.collection.v2``)::

    collection.json        one entry per valid elite, worst first (see :func:`build_collection`)
    levels/level_0000.txt  level files (``dsage-ray maze eval --layout`` / ``dsage-ray mario eval --level``)
    levels/level_0000.png  the level with the agent's occupancy (Mario: and path), one colour scale for all
    heatmap.png            the re-evaluated archive
    report.html            self-contained report (:mod:`dsage_ray.audit.report`)
"""

from __future__ import annotations

import json
import re
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.config import RunConfig, resumed_config
from dsage_ray.domains import DEFAULT_DOMAIN, build_domain, domain_names, get_domain
from dsage_ray.errors import InputError
from dsage_ray.audit.collection_file import COLLECTION_FILE, FORMAT
from dsage_ray.audit.report import write_report
from dsage_ray.io import atomic_write_json, replace_dir, staging_dir
from dsage_ray.types import EvaluationResult, Evaluator, Solutions

_SEED_TAG = 0xC011EC7  # keeps collection seeds apart from the runner's evaluation seeds
SEED_RULE = "seed = SeedSequence([run_seed, 0xC011EC7, rank in the search's worst-first order])"


def agent_slug(spec: str) -> str:
    """A short file-name-safe name for an agent spec (``dcd:/x/accel.tar?a=1`` → ``accel_tar``)."""
    return re.sub(r"[^A-Za-z0-9]+", "_", spec.split("?")[0].rstrip("/").split("/")[-1]).strip("_")[:40] or "agent"


def audit_config(
    *,
    domain: str = DEFAULT_DOMAIN,
    agent: str | None = None,
    reference: str | None = None,
    preset: str = "cpu",
    variant: str = "dsage",
    objective: str | None = None,
    measures: Sequence[str] | None = None,
    budget: int | None = None,
    seed: int = 0,
    name: str | None = None,
    overrides: dict[str, Any] | None = None,
    started: RunConfig | None = None,
) -> RunConfig:
    """The run config of an audit: DSAGE on ``domain`` with one of the domain's failure-eliciting objectives.

    Args:
        domain: A registered domain with an ``audit`` declaration (``maze``, ``mario``).
        agent: The agent spec to audit (default: the registration's ``audit.default_agent``).
        reference: A reference agent spec, for a domain with a ``regression`` audit objective (Maze); the
            audit then searches for levels where ``agent`` does worse than it.
        preset: The domain's preset (``cpu``, ``tiny``, ...).
        variant: The search: ``dsage`` (default), or any variant of the domain (``map_elites``, ``dr``, ...),
            e.g. to compare how many failures each finds at the same budget.
        objective: One of the registration's ``audit.objectives`` (default: its first, or ``regression`` with a
            reference).
        measures: Measure names (default: the registration's ``audit.measures``).
        budget: Real evaluations (default: the preset's).
        seed: Run seed; also seeds the collection's re-evaluations.
        name: Run name, the Tune experiment folder (default ``audit_<agent>``).
        overrides: Further dotted config keys (``--set``), applied last. Audits hold no levels out
            (``experimental.holdout_levels = 0``) unless these say otherwise, and a DSAGE search also takes the
            registration's ``audit.surrogate_keys`` (Maze: ``selection.elite_mutants = 150``). A DSAGE search with
            a time budget runs as ``search = "auto"`` unless these name a ``search`` (or ``auto`` cannot run: with
            ``pipeline`` or ``surrogate.init``). ``search = "auto"`` runs as ``fixed`` where the registration's
            ``audit.auto_keeps_dsage`` says why (Maze).
        started: The config of the search this audit continues (``--resume``, ``--collect-only``). Every key
            the arguments here do not name (a preset's, a registration's ``audit.surrogate_keys``, the
            search) then keeps the value it was started with, so an audit begun under an earlier default
            continues as it began; a named key that differs is refused when the checkpoint loads.

    Raises:
        ValueError: An unknown domain, an agent of a kind the domain does not play, or an objective or
            measure it cannot audit with.
    """
    spec = audit_spec(domain)
    cls = spec.domain_class()
    agent = agent or spec.audit.default_agent
    for role in filter(None, (agent, reference)):
        spec.check_agent(role)
    values: dict[str, Any] = {"name": name or f"audit_{agent_slug(agent)}", "domain": domain, "variant": variant,
                              "preset": preset, "seed": seed}
    values.update(cls.audit_values(agent=agent, reference=reference, objective=objective, measures=measures))
    if budget is not None:
        values["budget"] = budget
    # The audit's own defaults, below the arguments: a resumed audit keeps the values it began with.
    # The held-out levels are a diagnostic of the surrogate for research runs (about 10% of a cpu run's
    # time); an audit wants failures, so it holds none out unless asked (--set experimental.holdout_levels=100).
    defaults: dict[str, Any] = {"experimental.holdout_levels": 0}
    # A domain may leave the measures to its config section (the gym domain's space file names them).
    num_measures = len(values.get(f"{domain}.measures", ()))
    if num_measures not in (0, 2):
        # The presets' downsampling blocks are per measure for the usual two; keep their scale otherwise.
        defaults["selection.block"] = (4,) * num_measures
    keys = {**defaults, **values, **(overrides or {})}
    config = RunConfig.build(keys)
    if spec.audit.surrogate_keys and config.mutates_elites:
        keys = {**defaults, **spec.audit.surrogate_keys, **values, **(overrides or {})}
    if "search" not in (overrides or {}) and config.time_budget > 0 and config.can_search_auto:
        # With a time budget, DSAGE may not have the time to pay for its surrogate: in 5-minute Mario audits it
        # did not get past its random levels, and auto found 1.7x its failing cells (docs/DECISIONS.md).
        keys["search"] = "auto"
    # An audit begun with auto before the domain kept DSAGE continues as it began, even when auto is asked again.
    if keys.get("search") == "auto" and spec.audit.auto_keeps_dsage and (started is None or started.search != "auto"):
        keys["search"] = "fixed"
    config = RunConfig.build(keys)
    if started is None:
        return config
    return resumed_config(config, started, given={*values, *(overrides or {})})


def audit_spec(domain: str):
    """The registration of ``domain``, checked to declare audits (:class:`~dsage_ray.domains.AuditSpec`).

    Raises:
        InputError: An unknown domain, or one without an ``audit`` declaration.
    """
    spec = get_domain(domain)
    if spec.audit is None:
        raise InputError(f"domain {domain!r} declares no audit (auditable: {', '.join(_auditable_names()) or 'none'})")
    return spec


def _auditable_names() -> list[str]:
    names = []
    for name in domain_names():
        try:
            if get_domain(name).audit is not None:
                names.append(name)
        except InputError:  # a plug-in that does not load is not listed
            continue
    return names


def level_seed(run_seed: int, rank: int) -> int:
    """The recorded evaluation seed of collection entry ``rank``."""
    return int(np.random.SeedSequence([int(run_seed), _SEED_TAG, int(rank)]).generate_state(1)[0])


def reevaluate(evaluator: Evaluator, solutions: Solutions, seeds: Sequence[int], *, desc: str
               ) -> list[EvaluationResult]:
    """Evaluates ``solutions`` with their seeds, with a progress bar; failures retried once.

    Args:
        evaluator: In-process or the Ray simulator pool (which replaces an actor that dies and re-runs its
            work, so a dying simulator loses no level).
        solutions: The levels.
        seeds: One seed per level.
        desc: The bar's label (it moves per level in-process, per chunk on the pool).

    Returns:
        One result per solution, in order (failed twice: ``failed`` with the error).
    """
    from tqdm import tqdm

    from dsage_ray.core.evaluation import evaluate_with_retry

    with tqdm(total=len(solutions), desc=desc, unit="level", dynamic_ncols=True) as bar:
        return evaluate_with_retry(evaluator, solutions, list(seeds), progress=lambda done: bar.update(done - bar.n))


def build_collection(
    archive,
    *,
    config: RunConfig,
    out_dir: str | Path,
    evaluator: Evaluator | None = None,
    max_levels: int | None = None,
    search_dir: str | Path | None = None,
    nominal: dict[str, Any] | None = None,
) -> Path:
    """Re-evaluates the valid elites of ``archive`` and writes the collection folder (module docstring).

    Entries are sorted worst first by their re-evaluated objective (for a regression audit: the largest
    regression first), ties in the search's order. Each holds the generic keys of the collection format
    (``id``, ``level_file``, ``image_file``, ``objective``, ``success_rate``, ``measures``, ``seed``,
    ``episodes``, ``reproduce``, ``search_objective``, ``search_measures``), the domain's own numbers
    (``entry_fields``) and, in a regression audit, ``reference`` (the reference agent's numbers,
    ``reference_numbers``, with the same ``seed``) and ``regression`` (reference − audited success rate).

    Args:
        archive: The search's ground-truth archive.
        config: The audit's run config (agent, objective, measures, episodes per re-evaluation).
        out_dir: The collection folder; written whole, then swapped in. The ``reproduce`` commands name
            the level files by absolute path, so they run from any directory (and not after a move); the
            report shows them with the path relative to the folder
            (:func:`~dsage_ray.audit.report.portable_command`), to run in it, wherever it is.
        evaluator: Evaluates ``(solutions, seeds)`` with a domain built from ``config``; default in-process
            (the Ray simulator pool fits here too).
        max_levels: Keep only the elites the search rated worst (all by default).
        search_dir: Recorded in the collection for provenance.
        nominal: The audit's nominal check (:meth:`dsage_ray.audit.nominal.NominalCheck.to_dict`), recorded as
            ``nominal`` for the report's header.

    Returns:
        ``out_dir``.
    """
    from dsage_ray.core.evaluation import InProcessEvaluator
    from dsage_ray.core.outputs import heatmap_png
    from dsage_ray.qd.archives import make_archive

    domain = build_domain(config)
    evaluator = evaluator or InProcessEvaluator(domain=domain, threads=config.torch_threads)
    objective_name = config.domain_config.objective
    data = archive.data()
    solutions = np.asarray(data["solution"])
    valid = np.array([domain.is_valid(s) for s in solutions], dtype=bool)
    # Worst first by the search's own verdict; the stable sort keeps archive order among ties.
    order = [int(i) for i in np.argsort(-np.asarray(data["objective"]), kind="stable") if valid[i]]
    if max_levels is not None:
        order = order[:max_levels]
    seeds = [level_seed(config.seed, rank) for rank in range(len(order))]
    results = (reevaluate(evaluator, solutions[order], seeds, desc="re-evaluating the collection")
               if order else [])

    # A level whose evaluation failed twice has no numbers to reproduce; it is counted, not shown.
    entries = [
        {"solution": solutions[index], "result": result, "seed": seed,
         "search_objective": float(data["objective"][index]),
         "search_measures": np.asarray(data["measures"][index], dtype=float).tolist()}
        for index, seed, result in zip(order, seeds, results) if not result.failed
    ]
    entries.sort(key=lambda e: (-e["result"].objective, domain.success_rate(e["result"])))
    # One colour scale for every picture of the collection, so a dark cell means the same on each.
    peak = max((float(np.max(e["result"].occupancy)) for e in entries), default=0.0)
    occupancy_max = peak if peak > 0 else None

    out_dir = Path(out_dir)
    staging = staging_dir(out_dir)
    (staging / "levels").mkdir()
    records = []
    for rank, entry in enumerate(entries):
        solution, result, seed = entry["solution"], entry["result"], entry["seed"]
        stem = f"levels/level_{rank:04d}"
        level_file, image_file = f"{stem}.txt", f"{stem}.png"
        (staging / level_file).write_text(domain.level_text(solution))
        success = domain.success_rate(result)
        record: dict[str, Any] = {
            "id": rank,
            "level_file": level_file,
            "image_file": image_file,
            "objective": float(result.objective),
            "success_rate": success,
            "measures": dict(zip(domain.measure_names, map(float, result.measures))),
            "seed": int(seed),
            "episodes": int(domain.episodes),
            # Absolute, so the command runs from any directory of this machine (not only where the audit was
            # started); the report shows it relative to the collection folder, which works wherever it moves.
            "reproduce": domain.reproduce_command(out_dir.resolve() / level_file, seed=seed),
            "search_objective": entry["search_objective"],
            "search_measures": dict(zip(domain.measure_names, entry["search_measures"])),
        }
        reference = domain.reference_numbers(result)
        if reference is not None:
            record["reference"] = {**reference, "seed": int(seed)}
            record["regression"] = float(reference["success_rate"]) - success
        record.update(domain.entry_fields(solution, result, level_file=level_file))
        # The picture names its level and no number: the report's card shows the numbers beside it once.
        (staging / image_file).write_bytes(domain.render_evaluation(solution, result, title=f"level #{rank}",
                                                                    occupancy_max=occupancy_max))
        records.append(record)

    heatmap_archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims,
                                   ranges=domain.measure_ranges, solution_dtype=domain.solution_dtype)
    if entries:
        heatmap_archive.add(np.array([e["solution"] for e in entries]),
                            np.array([e["result"].objective for e in entries]),
                            np.array([e["result"].measures for e in entries]))
    against = f" vs {domain.reference_spec}" if domain.reference_spec else ""
    (staging / "heatmap.png").write_bytes(heatmap_png(
        heatmap_archive, measure_names=domain.measure_names,
        title=f"{objective_name} of {domain.agent_spec}{against} ({len(entries)} levels, re-evaluated)"))

    collection = {
        "format": FORMAT,
        "domain": config.domain,
        "agent": domain.agent_spec,
        "reference": domain.reference_spec,
        "objective": objective_name,
        "measures": list(domain.measure_names),
        "measure_ranges": [list(r) for r in domain.measure_ranges],
        "archive_dims": list(domain.archive_dims),
        "episodes": int(domain.episodes),
        "seed_rule": SEED_RULE,
        "run_seed": int(config.seed),
        "search_dir": None if search_dir is None else str(search_dir),
        "search_elites": int(len(solutions)),
        "search_invalid_elites": int((~valid).sum()),
        "failed_reevaluations": len(order) - len(entries),
        "config": config.to_dict(),
        "created": time.strftime("%Y-%m-%d %H:%M:%S"),
        "levels": records,
        **domain.collection_fields(),
    }
    if nominal is not None:
        collection["nominal"] = nominal
    atomic_write_json(staging / COLLECTION_FILE, collection)
    write_report(staging)
    replace_dir(staging, out_dir)
    return out_dir
