"""Two agents on one saved collection, same levels, same seeds: where is B worse than A, and where better?

Each level is re-run from its layout file with its recorded seed and episode count, for both agents, so the
two evaluations share the initial headings (drawn first from the seed) and differ only in the policy.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from dsage_ray.audit.collection import evaluate_entry, load_collection

#: A success-rate difference larger than this counts as "worse"/"better".
DEFAULT_THRESHOLD = 0.1
#: Levels pictured on the HTML page.
PICTURED = 8


def compare_agents(
    agent_a: str,
    agent_b: str,
    *,
    collection_dir: str | Path,
    threshold: float = DEFAULT_THRESHOLD,
    episodes: int | None = None,
    html_path: str | Path | None = None,
) -> dict[str, Any]:
    """Evaluates both agents on every level of a collection and ranks the levels by B − A.

    Args:
        agent_a: Reference agent spec.
        agent_b: Agent spec under test.
        collection_dir: A folder written by :func:`dsage_ray.audit.collection.build_collection`.
        threshold: Success-rate difference that counts as a change.
        episodes: Override the recorded episodes per level (seeds stay the recorded ones).
        html_path: Where to write the HTML page (none when None).

    Returns:
        ``{"agent_a", "agent_b", "levels": [...], "summary": {...}}``; levels sorted with B's worst
        regressions first, each with ``success_a/b``, ``path_a/b`` and ``verdict``
        (``worse``/``better``/``same``).
    """
    from dsage_ray.agents import load_agent
    from dsage_ray.domains.maze.render import render_level

    collection_dir = Path(collection_dir)
    collection = load_collection(collection_dir)
    agents = load_agent(agent_a), load_agent(agent_b)
    see_through = collection["see_through_walls"]
    rows, occupancy_b, levels = [], {}, {}
    for entry in collection["levels"]:
        (level, ra), (_, rb) = (evaluate_entry(entry, agent, collection_dir=collection_dir,
                                               see_through_walls=see_through, episodes=episodes) for agent in agents)
        delta = rb.success_rate - ra.success_rate
        verdict = "worse" if delta < -threshold else "better" if delta > threshold else "same"
        rows.append({"id": entry["id"], "layout_file": entry["layout_file"], "seed": entry["seed"],
                     "episodes": ra.episodes, "success_a": ra.success_rate, "success_b": rb.success_rate,
                     "path_a": ra.mean_path_length, "path_b": rb.mean_path_length, "verdict": verdict})
        occupancy_b[entry["id"]], levels[entry["id"]] = rb.occupancy, level
    # B's biggest regressions first; among equal success, the larger path-length increase first.
    rows.sort(key=lambda r: (r["success_b"] - r["success_a"], -(r["path_b"] - r["path_a"])))
    n = max(len(rows), 1)
    summary = {
        "levels": len(rows),
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
    comparison = {"agent_a": agent_a, "agent_b": agent_b, "collection": str(collection_dir), "levels": rows,
                  "summary": summary,
                  "episodes_note": (f"{episodes} episodes" if episodes else "its recorded episode count")}
    if html_path is not None:
        from dsage_ray.audit.report import write_compare_report

        pictured = [r for r in rows if r["verdict"] == "worse"][:PICTURED]
        images = {r["id"]: render_level(levels[r["id"]], occupancy_b[r["id"]],
                                        title=f"B on #{r['id']}: success {r['success_b']:.2f} (A {r['success_a']:.2f})")
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
    header = f"{'id':>5}  {'layout':<22} {'succ A':>6} {'succ B':>6} {'Δ':>6} {'path A':>7} {'path B':>7}"
    for title, rows in (("B worse than A", [r for r in comparison["levels"] if r["verdict"] == "worse"][:limit]),
                        ("B better than A", [r for r in reversed(comparison["levels"])
                                             if r["verdict"] == "better"][:limit])):
        lines += ["", f"{title} ({len(rows)} shown)", header]
        lines += [f"{r['id']:>5}  {r['layout_file']:<22} {r['success_a']:6.2f} {r['success_b']:6.2f} "
                  f"{r['success_b'] - r['success_a']:+6.2f} {r['path_a']:7.1f} {r['path_b']:7.1f}" for r in rows]
    return "\n".join(lines)
