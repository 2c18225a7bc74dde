"""Audits: a failure-eliciting DSAGE search, then a reproducible *collection* of the mazes it found.

An audit is an ordinary DSAGE run (the runner, the Ray layer, the Maze domain: nothing re-implemented)
whose objective rewards the agent doing badly on a valid level (``failure_rate`` by default, or
``regret``) and whose measures describe the level (default ``num_walls`` × ``optimal_path_length``).

**Seeds and reproducibility.** The search archive keeps each elite's solution and the numbers of the
evaluation that placed it, but not that evaluation's seed (the runner derives it from the run seed and the
evaluation's index, which the archive does not store). Rather than widen the archive, the collection
**re-evaluates every elite** with a fresh seed derived from the run seed and the elite's rank
(:func:`level_seed`) and records that seed next to the numbers. Every number in ``collection.json`` is
therefore the output of ``evaluate(level, agent, episodes=E, seed=S)`` for the level's layout file and the
recorded ``E`` and ``S``: ``dsage-ray maze eval --agent A --layout levels/L.txt --episodes E --seed S``
prints them again. A side effect is honest numbers: elites are the search's *luckiest* evaluations, and a
fresh evaluation removes that selection bias (the search's own value is kept as ``search_objective``).

Collection folder::

    collection.json        one entry per valid elite, worst first (see :func:`build_collection`)
    levels/level_0000.txt  layout files (``dsage-ray maze eval --layout`` reads them)
    levels/level_0000.png  the level with the agent's occupancy overlay
    heatmap.png            the re-evaluated archive
    report.html            self-contained report (:mod:`dsage_ray.audit.report`)
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.io import atomic_write_json, replace_dir, staging_dir
from dsage_ray.types import Evaluator

COLLECTION_FILE = "collection.json"
FORMAT = "dsage_ray.collection.v1"
#: Measures of the default audit: what the level looks like, not what the agent did.
DEFAULT_MEASURES = ("num_walls", "optimal_path_length")
#: The paper's Maze measures.
PAPER_MEASURES = ("num_walls", "mean_path_length")
_SEED_TAG = 0xC011EC7  # keeps collection seeds apart from the runner's evaluation seeds


def audit_config(
    *,
    agent: str,
    preset: str = "cpu",
    objective: str = "failure_rate",
    measures: Sequence[str] = DEFAULT_MEASURES,
    budget: int | None = None,
    seed: int = 0,
    name: str = "audit",
    overrides: dict[str, Any] | None = None,
) -> RunConfig:
    """The run config of an audit: DSAGE on the Maze with a failure-eliciting objective.

    Args:
        agent: The agent spec to audit.
        preset: Maze preset (``cpu``, ``paper``, ``tiny``).
        objective: ``failure_rate`` or ``regret`` (``validity`` would search for valid mazes, not failures).
        measures: Measure names (:mod:`dsage_ray.domains.maze.measures`); archive cells are one per
            integer value of each measure's natural range unless ``overrides`` set ``maze.archive_dims``.
        budget: Real evaluations (default: the preset's).
        seed: Run seed; also seeds the collection's re-evaluations.
        name: Run name (the Tune experiment folder).
        overrides: Further dotted config keys (``--set``), applied last.
    """
    if objective not in ("failure_rate", "regret"):
        raise ValueError(f"audit objective must be 'failure_rate' or 'regret', got {objective!r}")
    from dsage_ray.domains.maze.measures import get_measure

    def cells(name: str) -> int:
        # One cell per integer value of the measure's natural range; 50 for the fractions in [0, 1].
        low, high = get_measure(name).natural_range(16, 16)
        return 50 if high - low <= 1 else int(round(high - low))

    values: dict[str, Any] = {
        "name": name, "domain": "maze", "variant": "dsage", "preset": preset, "seed": seed,
        "maze.agent": agent, "maze.objective": objective, "maze.measures": tuple(measures),
        "maze.archive_dims": tuple(cells(m) for m in measures),
    }
    if len(measures) != 2:
        # The presets' downsampling blocks are per measure for the usual two; keep their scale otherwise.
        values["selection.block"] = (4,) * len(measures)
    if budget is not None:
        values["budget"] = budget
    values.update(overrides or {})
    return RunConfig.build(values)


def level_seed(run_seed: int, rank: int) -> int:
    """The recorded evaluation seed of collection entry ``rank``."""
    return int(np.random.SeedSequence([int(run_seed), _SEED_TAG, int(rank)]).generate_state(1)[0])


def build_collection(
    archive,
    *,
    config: RunConfig,
    out_dir: str | Path,
    evaluator: Evaluator | None = None,
    max_levels: int | None = None,
    search_dir: str | Path | None = None,
) -> Path:
    """Re-evaluates the valid elites of ``archive`` and writes the collection folder (module docstring).

    Args:
        archive: The search's ground-truth archive (solutions are wall bitmaps).
        config: The audit's run config (agent, objective, measures, ``maze.episodes`` per re-evaluation).
        out_dir: The collection folder; written whole, then swapped in.
        evaluator: Evaluates ``(solutions, seeds)`` with a domain built from ``config``; default in-process
            (the Ray simulator pool fits here too).
        max_levels: Keep only the elites the search rated worst (all by default).
        search_dir: Recorded in the collection for provenance.

    Returns:
        ``out_dir``.
    """
    from dsage_ray.core.evaluation import InProcessEvaluator, evaluate_with_retry
    from dsage_ray.core.outputs import heatmap_png
    from dsage_ray.domains.maze.layout import format_layout
    from dsage_ray.domains.maze.render import render_level
    from dsage_ray.qd.archives import make_archive

    domain = build_domain(config)
    evaluator = evaluator or InProcessEvaluator(domain=domain)
    data = archive.data()
    solutions = np.asarray(data["solution"])
    valid = np.array([domain.level(s).valid for s in solutions], dtype=bool)
    # Worst first by the search's own verdict; the stable sort keeps archive order among ties.
    order = [int(i) for i in np.argsort(-np.asarray(data["objective"]), kind="stable") if valid[i]]
    if max_levels is not None:
        order = order[:max_levels]
    seeds = [level_seed(config.seed, rank) for rank in range(len(order))]
    results = evaluate_with_retry(evaluator, solutions[order], seeds) if order else []

    out_dir = Path(out_dir)
    staging = staging_dir(out_dir)
    (staging / "levels").mkdir()
    entries = []
    for rank, (index, seed, result) in enumerate(zip(order, seeds, results)):
        if result.failed:
            continue  # failed twice (recorded by the evaluator's log); nothing reproducible to show
        level = domain.level(solutions[index])
        entries.append({
            "solution": solutions[index], "level": level, "result": result, "seed": seed,
            "search_objective": float(data["objective"][index]),
            "search_measures": np.asarray(data["measures"][index], dtype=float).tolist(),
        })
    # Worst first by the re-evaluated numbers (what the report shows), ties by mean path length.
    entries.sort(key=lambda e: (-e["result"].objective, -e["result"].info["mean_path_length"]))

    records = []
    for rank, entry in enumerate(entries):
        level, result = entry["level"], entry["result"]
        stem = f"level_{rank:04d}"
        (staging / "levels" / f"{stem}.txt").write_text(format_layout(level))
        info = result.info
        title = (f"#{rank}: success {info['success_rate']:.2f}, mean path {info['mean_path_length']:.0f} "
                 f"(optimal {info['optimal_path_length']})")
        render_level(level, result.occupancy, staging / "levels" / f"{stem}.png", title=title)
        records.append({
            "id": rank,
            "layout_file": f"levels/{stem}.txt",
            "image_file": f"levels/{stem}.png",
            "layout": format_layout(level),
            "start": list(level.start),
            "goal": list(level.goal),
            "num_walls": level.num_walls,
            "optimal_path_length": int(info["optimal_path_length"]),
            "objective": float(result.objective),
            "measures": dict(zip(domain.measure_names, map(float, result.measures))),
            "success_rate": float(info["success_rate"]),
            "mean_path_length": float(info["mean_path_length"]),
            "episode_lengths": [int(x) for x in info["episode_lengths"]],
            "explored_fraction": float(info["explored_fraction"]),
            "repeated_visits": float(info["repeated_visits"]),
            "seed": int(entry["seed"]),
            "episodes": int(config.maze.episodes),
            "search_objective": entry["search_objective"],
            "search_measures": dict(zip(domain.measure_names, entry["search_measures"])),
        })

    heatmap_archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims,
                                   ranges=domain.measure_ranges, solution_dtype=domain.solution_dtype)
    if entries:
        heatmap_archive.add(np.array([e["solution"] for e in entries]),
                            np.array([e["result"].objective for e in entries]),
                            np.array([e["result"].measures for e in entries]))
    (staging / "heatmap.png").write_bytes(heatmap_png(
        heatmap_archive, measure_names=domain.measure_names,
        title=f"{config.maze.objective} of {config.maze.agent} ({len(entries)} levels, re-evaluated)"))

    collection = {
        "format": FORMAT,
        "agent": config.maze.agent,
        "objective": config.maze.objective,
        "measures": list(domain.measure_names),
        "measure_ranges": [list(r) for r in domain.measure_ranges],
        "archive_dims": list(domain.archive_dims),
        "episodes": int(config.maze.episodes),
        "see_through_walls": bool(config.maze.see_through_walls),
        "seed_rule": "seed = SeedSequence([run_seed, 0xC011EC7, rank in the search's worst-first order])",
        "run_seed": int(config.seed),
        "search_dir": None if search_dir is None else str(search_dir),
        "search_elites": int(len(solutions)),
        "search_invalid_elites": int((~valid).sum()),
        "config": config.to_dict(),
        "created": time.strftime("%Y-%m-%d %H:%M:%S"),
        "levels": records,
    }
    atomic_write_json(staging / COLLECTION_FILE, collection)
    from dsage_ray.audit.report import write_report

    write_report(staging)
    replace_dir(staging, out_dir)
    return out_dir


def load_collection(path: str | Path) -> dict[str, Any]:
    """Reads a collection folder's ``collection.json`` (or the file itself); ValueError when it is not one."""
    path = Path(path)
    file = path / COLLECTION_FILE if path.is_dir() else path
    try:
        collection = json.loads(file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{file}: not a readable collection ({exc})") from None
    if not isinstance(collection, dict) or collection.get("format") != FORMAT:
        raise ValueError(f"{file}: not a dsage_ray collection (expected format {FORMAT})")
    return collection


def evaluate_entry(entry: dict[str, Any], agent, *, collection_dir: str | Path, see_through_walls: bool = True,
                   episodes: int | None = None, seed: int | None = None):
    """Re-runs one collection entry from its layout file: its recorded seed and episodes unless overridden."""
    from dsage_ray.domains.maze import evaluate, load_layout

    level = load_layout(Path(collection_dir) / entry["layout_file"])
    return level, evaluate(level, agent, episodes=episodes or entry["episodes"],
                           seed=entry["seed"] if seed is None else seed, see_through_walls=see_through_walls)
