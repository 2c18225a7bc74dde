"""Two agents on one saved collection, same levels, same seeds: where is B worse than A, and where better?

Any auditable domain compares (:class:`~dsage_ray.types.AuditableDomain`): each level of the collection is
turned back into its solution (``entry_solution``) and evaluated once per agent, with the collection's
settings, the level's recorded seed and its episode count. The two evaluations of a level share whatever
the seed draws (the Maze's initial headings), so they differ only in the policy. What is compared is the
success rate and each of the registration's report columns that has a ``mean`` (Maze: the mean path length;
Mario: the completion). It runs in this process or on the Ray simulator pool (``workers``), whose replaced
actors lose no level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.audit.collection import audit_spec, reevaluate
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.config import RunConfig, flatten
from dsage_ray.domains import ReportField
from dsage_ray.types import Solutions

#: A success-rate difference larger than this counts as "worse"/"better".
DEFAULT_THRESHOLD = 0.1
#: Levels pictured on the HTML page.
PICTURED = 8


def comparison_config(collection: dict[str, Any], agent: str, *, episodes: int | None = None,
                      workers: int | None = None) -> RunConfig:
    """The collection's run config turned into a one-agent evaluation of ``agent`` (the domain's default
    audit objective, the collection's measures, its episodes).

    Raises:
        ValueError: The collection's domain declares no audit or does not play ``agent``'s kind, or the
            levels were evaluated with mixed episode counts and ``episodes`` is None.
    """
    spec = audit_spec(collection["domain"])
    spec.check_agent(agent)
    recorded = {int(level["episodes"]) for level in collection["levels"]} or {int(collection["episodes"])}
    if episodes is None and len(recorded) > 1:
        raise ValueError(f"the collection's levels were evaluated with different episode counts {sorted(recorded)}; "
                         f"pass --episodes")
    values = flatten(collection["config"])
    values.update(spec.domain_class().audit_values(agent=agent, measures=collection["measures"]))
    values[spec.audit.episodes_key] = int(episodes or recorded.pop())
    if workers is not None:
        values["ray.num_workers"] = workers
    return RunConfig.build(values)


def compared_columns(domain: str) -> list[ReportField]:
    """The registration's report columns that ``compare`` shows per agent (those with a ``mean``)."""
    return [column for column in audit_spec(domain).audit.columns if column.mean]


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
        ``{"agent_a", "agent_b", "domain", "columns", "levels": [...], "summary": {...}, "failed"}``; levels
        sorted with B's worst regressions first (ties: B's larger audit objective first, then by id), each
        with ``level_file``, ``seed``, ``success_a``/``success_b``, ``KEY_a``/``KEY_b`` per compared column
        KEY (``columns``: Maze ``mean_path_length``) and ``verdict`` (``worse``/``better``/``same``).

    Raises:
        ValueError: A collection of a domain without audits, an agent the domain does not play or that
            cannot be loaded, or a level that cannot be read back.
    """
    from dsage_ray.domains import build_domain

    collection_dir = Path(collection_dir)
    collection = load_collection(collection_dir)
    configs = [comparison_config(collection, agent, episodes=episodes, workers=workers) for agent in (agent_a, agent_b)]
    domains = [build_domain(config) for config in configs]
    for domain in domains:
        domain.preflight()  # both agents load here, in one line if they cannot, before any simulator starts
    entries = collection["levels"]
    domain = domains[1]
    solutions = np.zeros((len(entries), domain.solution_dim), dtype=domain.solution_dtype)
    for i, entry in enumerate(entries):
        solutions[i] = domain.entry_solution(entry, collection_dir)
    seeds = [int(entry["seed"]) for entry in entries]
    results_a, results_b = (_evaluate(config, own, solutions, seeds, workers=workers, desc=f"comparing, agent {role}")
                            for role, config, own in zip("AB", configs, domains))

    columns = compared_columns(collection["domain"])
    rows, failed = [], []
    for i, (entry, a, b) in enumerate(zip(entries, results_a, results_b)):
        if a.failed or b.failed:
            failed.append({"id": entry["id"], "error": a.error if a.failed else b.error})
            continue
        row = {"id": entry["id"], "level_file": entry["level_file"], "seed": entry["seed"], "episodes": domain.episodes}
        for role, result, own in (("a", a, domains[0]), ("b", b, domains[1])):
            fields = own.entry_fields(solutions[i], result, level_file=entry["level_file"])
            row[f"success_{role}"] = own.success_rate(result)
            row[f"objective_{role}"] = float(result.objective)
            row.update({f"{column.key}_{role}": float(fields[column.key]) for column in columns})
        delta = row["success_b"] - row["success_a"]
        row["verdict"] = "worse" if delta < -threshold else "better" if delta > threshold else "same"
        rows.append(row | {"_index": i})
    rows.sort(key=lambda r: (r["success_b"] - r["success_a"], -(r["objective_b"] - r["objective_a"]), r["id"]))
    n = max(len(rows), 1)
    means = ["success", *(column.key for column in columns)]
    summary = {
        "levels": len(rows),
        "failed": len(failed),
        "threshold": threshold,
        **{f"{key}_{role}": sum(r[f"{key}_{role}"] for r in rows) / n for key in means for role in "ab"},
        "solved_a": sum(r["success_a"] == 1.0 for r in rows),
        "solved_b": sum(r["success_b"] == 1.0 for r in rows),
        "b_worse": sum(r["verdict"] == "worse" for r in rows),
        "b_better": sum(r["verdict"] == "better" for r in rows),
    }
    indices = {r["id"]: r.pop("_index") for r in rows}
    comparison = {"agent_a": agent_a, "agent_b": agent_b, "domain": collection["domain"],
                  "columns": [{"key": c.key, "label": c.name, "mean": c.mean} for c in columns],
                  "collection": str(collection_dir), "levels": rows, "summary": summary, "failed": failed,
                  "episodes_note": (f"{episodes} episodes" if episodes else "its recorded episode count")}
    if html_path is not None:
        from dsage_ray.audit.report import write_compare_report

        pictured = [r for r in rows if r["verdict"] == "worse"][:PICTURED]
        # One colour scale for all pictures of the page.
        peak = max((float(results_b[indices[r["id"]]].occupancy.max()) for r in pictured), default=0.0)
        images = {r["id"]: domain.render_evaluation(solutions[indices[r["id"]]], results_b[indices[r["id"]]],
                                                    title=f"B on #{r['id']}: success {r['success_b']:.2f} "
                                                          f"(A {r['success_a']:.2f})",
                                                    occupancy_max=peak if peak > 0 else None)
                  for r in pictured}
        write_compare_report(html_path, comparison, collection_dir=collection_dir, images=images)
    return comparison


def _evaluate(config: RunConfig, domain, solutions: Solutions, seeds: Sequence[int], *, workers: int | None,
              desc: str) -> list:
    """``solutions`` evaluated with ``seeds`` by ``domain`` in this process, or by a Ray pool of ``workers``."""
    from dsage_ray.core.evaluation import InProcessEvaluator

    if not workers:
        return reevaluate(InProcessEvaluator(domain=domain, threads=config.torch_threads), solutions, seeds, desc=desc)
    from dsage_ray.ray.pool import SimulatorPool

    pool = SimulatorPool(config=config)
    try:
        return reevaluate(pool, solutions, seeds, desc=desc)
    finally:
        pool.close()


def format_comparison(comparison: dict[str, Any], *, limit: int = 10) -> str:
    """The terminal table: summary, then the ``limit`` largest regressions and improvements of B."""
    s = comparison["summary"]
    a, b = comparison["agent_a"], comparison["agent_b"]
    columns = comparison.get("columns", [])
    means = "".join(f"; {c['mean']} A {s[c['key'] + '_a']:.3g}  B {s[c['key'] + '_b']:.3g}" for c in columns)
    lines = [
        f"A = {a}",
        f"B = {b}",
        f"{s['levels']} levels; mean success A {s['success_a']:.3f}  B {s['success_b']:.3f}{means}",
        f"B worse on {s['b_worse']} levels, better on {s['b_better']} (|Δ success| > {s['threshold']:.2f})",
    ]
    if s.get("failed"):
        lines.append(f"{s['failed']} levels left out: their evaluation failed twice "
                     f"(first: {comparison['failed'][0]['error']})")
    # Per compared column, its A and B values, each as wide as its header.
    cells = [(c["key"] + "_" + role, f"{c['label']} {role.upper()}") for c in columns for role in "ab"]
    widths = [max(8, len(name)) for _, name in cells]
    header = (f"{'id':>5}  {'level':<22} {'succ A':>6} {'succ B':>6} {'Δ':>6}"
              + "".join(f" {name:>{w}}" for (_, name), w in zip(cells, widths)))
    for title, rows in (("B worse than A", [r for r in comparison["levels"] if r["verdict"] == "worse"][:limit]),
                        ("B better than A", [r for r in reversed(comparison["levels"])
                                             if r["verdict"] == "better"][:limit])):
        lines += ["", f"{title} ({len(rows)} shown)", header]
        lines += [f"{r['id']:>5}  {r['level_file']:<22} {r['success_a']:6.2f} {r['success_b']:6.2f} "
                  f"{r['success_b'] - r['success_a']:+6.2f}"
                  + "".join(f" {r[key]:>{w}.4g}" for (key, _), w in zip(cells, widths)) for r in rows]
    return "\n".join(lines)
