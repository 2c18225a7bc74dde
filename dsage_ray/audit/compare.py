"""Two agents on one saved collection, same levels, same seeds: where is B worse than A, and where better?

The comparison is the domain's ``regression`` audit evaluation (Maze's: a domain whose registration lists a
``regression`` audit objective) with B audited and A as the reference: each level is re-run from its level file with its recorded seed and episode count for both agents, so the two
evaluations share the initial headings (drawn first from the seed) and differ only in the policy. It runs
in this process or on the Ray simulator pool (``workers``), whose replaced actors lose no level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from dsage_ray.audit.collection import reevaluate
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.config import RunConfig, flatten

#: A success-rate difference larger than this counts as "worse"/"better".
DEFAULT_THRESHOLD = 0.1
#: Levels pictured on the HTML page.
PICTURED = 8


def comparison_config(collection: dict[str, Any], agent_a: str, agent_b: str, *, episodes: int | None = None,
                      workers: int | None = None) -> RunConfig:
    """The collection's run config turned into B's regression evaluation against A (domains that compare agents).

    Raises:
        ValueError: The collection's domain has no ``regression`` audit objective, or mixed episode counts.
    """
    from dsage_ray.audit.collection import audit_spec

    spec = audit_spec(collection["domain"])
    if "regression" not in spec.audit.objectives:
        raise ValueError(f"compare needs a collection of a domain that compares agents (a 'regression' audit "
                         f"objective); this one is {collection['domain']!r}: one agent only")
    recorded = {int(level["episodes"]) for level in collection["levels"]} or {int(collection["episodes"])}
    if episodes is None and len(recorded) > 1:
        raise ValueError(f"the collection's levels were evaluated with different episode counts {sorted(recorded)}; "
                         f"pass --episodes")
    values = flatten(collection["config"])
    values.update(spec.domain_class().audit_values(agent=agent_b, reference=agent_a, objective="regression",
                                                   measures=collection["measures"]))
    values[spec.audit.episodes_key] = int(episodes or recorded.pop())
    if workers is not None:
        values["ray.num_workers"] = workers
    return RunConfig.build(values)


def compare_agents(
    agent_a: str,
    agent_b: str,
    *,
    collection_dir: str | Path,
    threshold: float = DEFAULT_THRESHOLD,
    episodes: int | None = None,
    html_path: str | Path | None = None,
    workers: int | None = None,
) -> dict[str, Any]:
    """Evaluates both agents on every level of a collection and ranks the levels by B − A.

    Args:
        agent_a: Reference agent spec.
        agent_b: Agent spec under test.
        collection_dir: A folder written by :func:`dsage_ray.audit.collection.build_collection`.
        threshold: Success-rate difference that counts as a change.
        episodes: Override the recorded episodes per level (seeds stay the recorded ones).
        html_path: Where to write the HTML page (none when None).
        workers: Evaluate on this many Ray simulator actors (default: in this process).

    Returns:
        ``{"agent_a", "agent_b", "levels": [...], "summary": {...}}``; levels sorted with B's worst
        regressions first, each with ``success_a/b``, ``path_a/b`` and ``verdict``
        (``worse``/``better``/``same``).

    Raises:
        ValueError: Not a Maze collection, an agent that cannot be loaded, or a layout file that does not
            match its level.
    """
    from dsage_ray.core.evaluation import InProcessEvaluator
    from dsage_ray.domains import build_domain

    collection_dir = Path(collection_dir)
    collection = load_collection(collection_dir)
    config = comparison_config(collection, agent_a, agent_b, episodes=episodes, workers=workers)
    domain = build_domain(config)
    domain.preflight()  # both agents load here, in one line if they cannot, before any simulator starts
    entries = collection["levels"]
    solutions = np.zeros((len(entries), domain.solution_dim), dtype=domain.solution_dtype)
    for i, entry in enumerate(entries):
        solutions[i] = domain.read_level(collection_dir / entry["level_file"])
    seeds = [int(entry["seed"]) for entry in entries]

    pool = None
    if workers:
        from dsage_ray.ray.pool import SimulatorPool

        pool = SimulatorPool(config=config)
    try:
        results = reevaluate(pool or InProcessEvaluator(domain=domain), solutions, seeds, desc="comparing",
                             workers=workers or 1)
    finally:
        if pool is not None:
            pool.close()

    rows, failed = [], []
    for i, (entry, result) in enumerate(zip(entries, results)):
        if result.failed:
            failed.append({"id": entry["id"], "error": result.error})
            continue
        reference, info = result.info["reference"], result.info
        delta = info["success_rate"] - reference["success_rate"]
        verdict = "worse" if delta < -threshold else "better" if delta > threshold else "same"
        rows.append({"id": entry["id"], "layout_file": entry["level_file"], "seed": entry["seed"],
                     "episodes": domain.episodes, "success_a": reference["success_rate"],
                     "success_b": info["success_rate"], "path_a": reference["mean_path_length"],
                     "path_b": info["mean_path_length"], "verdict": verdict, "_index": i})
    # B's biggest regressions first; among equal success, the larger path-length increase first.
    rows.sort(key=lambda r: (r["success_b"] - r["success_a"], -(r["path_b"] - r["path_a"])))
    n = max(len(rows), 1)
    summary = {
        "levels": len(rows),
        "failed": len(failed),
        "threshold": threshold,
        "success_a": sum(r["success_a"] for r in rows) / n,
        "success_b": sum(r["success_b"] for r in rows) / n,
        "path_a": sum(r["path_a"] for r in rows) / n,
        "path_b": sum(r["path_b"] for r in rows) / n,
        "solved_a": sum(r["success_a"] == 1.0 for r in rows),
        "solved_b": sum(r["success_b"] == 1.0 for r in rows),
        "b_worse": sum(r["verdict"] == "worse" for r in rows),
        "b_better": sum(r["verdict"] == "better" for r in rows),
    }
    indices = {r["id"]: r.pop("_index") for r in rows}
    comparison = {"agent_a": agent_a, "agent_b": agent_b, "collection": str(collection_dir), "levels": rows,
                  "summary": summary, "failed": failed,
                  "episodes_note": (f"{episodes} episodes" if episodes else "its recorded episode count")}
    if html_path is not None:
        from dsage_ray.audit.report import write_compare_report

        pictured = [r for r in rows if r["verdict"] == "worse"][:PICTURED]
        # One colour scale for all pictures of the page.
        peak = max((float(results[indices[r["id"]]].occupancy.max()) for r in pictured), default=0.0)
        images = {r["id"]: domain.render(solutions[indices[r["id"]]], results[indices[r["id"]]].occupancy,
                                         title=f"B on #{r['id']}: success {r['success_b']:.2f} "
                                               f"(A {r['success_a']:.2f})",
                                         occupancy_max=peak if peak > 0 else None)
                  for r in pictured}
        write_compare_report(html_path, comparison, collection_dir=collection_dir, images=images)
    return comparison


def format_comparison(comparison: dict[str, Any], *, limit: int = 10) -> str:
    """The terminal table: summary, then the ``limit`` largest regressions and improvements of B."""
    s = comparison["summary"]
    a, b = comparison["agent_a"], comparison["agent_b"]
    lines = [
        f"A = {a}",
        f"B = {b}",
        f"{s['levels']} levels; mean success A {s['success_a']:.3f}  B {s['success_b']:.3f}; "
        f"mean path A {s['path_a']:.1f}  B {s['path_b']:.1f}",
        f"B worse on {s['b_worse']} levels, better on {s['b_better']} (|Δ success| > {s['threshold']:.2f})",
    ]
    if s.get("failed"):
        lines.append(f"{s['failed']} levels left out: their evaluation failed twice "
                     f"(first: {comparison['failed'][0]['error']})")
    header = f"{'id':>5}  {'layout':<22} {'succ A':>6} {'succ B':>6} {'Δ':>6} {'path A':>7} {'path B':>7}"
    for title, rows in (("B worse than A", [r for r in comparison["levels"] if r["verdict"] == "worse"][:limit]),
                        ("B better than A", [r for r in reversed(comparison["levels"])
                                             if r["verdict"] == "better"][:limit])):
        lines += ["", f"{title} ({len(rows)} shown)", header]
        lines += [f"{r['id']:>5}  {r['layout_file']:<22} {r['success_a']:6.2f} {r['success_b']:6.2f} "
                  f"{r['success_b'] - r['success_a']:+6.2f} {r['path_a']:7.1f} {r['path_b']:7.1f}" for r in rows]
    return "\n".join(lines)
