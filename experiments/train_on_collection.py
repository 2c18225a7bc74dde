"""Does training on an audit's failures fix them, and failures it was not shown? (issue 19, item 3)

One readable experiment, top to bottom:

1. **Train.** For every seed, two arms continue the same trained module (``--init-from``) for the same number
   of env steps with ``experiments/train_maze_agent.py``: ``plain`` on fresh random mazes only, ``mixed`` with
   a share of its episodes replaying the levels of ``--collection`` (``--train-on-collection``). Continuing
   the audited agent is the loop a user runs: audit a checkpoint, then train it on what the audit found.
2. **Evaluate** the starting module and every trained one, with the same seeds for every agent, on
   - ``shown``: every level of ``--collection`` (the levels the mixed arm trained on), and among them those the
     audit found never solved (``shown, never solved``);
   - ``unseen``: the never-solved levels of ``--fresh``, a second audit of the starting module with another
     seed (levels identical to one of ``--collection`` are dropped): failures neither arm was shown;
   - ``random``: ``--mazes`` random valid mazes (the model card's set, ``benchmarks/bench_agents.py``).
3. **Print** the success rates per arm (mean ± standard error over seeds) and the mixed - plain difference
   paired by seed, and write ``results.json`` and ``summary.md`` in ``--out``.

Usage::

    dsage-ray audit --agent rllib:ppo_maze --preset cpu --budget 500 --seed 100 --local --out RUNS/loop/collection
    dsage-ray audit --agent rllib:ppo_maze --preset cpu --budget 500 --seed 101 --local --out RUNS/loop/fresh
    python experiments/train_on_collection.py --collection RUNS/loop/collection --fresh RUNS/loop/fresh \\
        --init-from ppo_maze --env-steps 200000 --seeds 0 1 2 --out RUNS/loop/train

A finished training (its ``progress.json`` at ``--env-steps``) is not run again, and the evaluations in
``results.json`` made with the same test sets and episodes are reused, so the command resumes.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import tyro

TRAIN_SCRIPT = Path(__file__).resolve().parent / "train_maze_agent.py"
ARMS = ("plain", "mixed")
SETS = ("shown", "unseen", "random")


@dataclasses.dataclass
class Args:
    """The experiment's flags: ``--help`` prints each with the description under it."""

    collection: str
    """the audit (or its collection folder) whose levels the mixed arm trains on"""
    fresh: str
    """a second audit of the starting module: its never-solved levels are the unseen test set"""
    out: str
    """experiment folder (trainings in OUT/tb_logs/, results.json, summary.md)"""
    init_from: str = "ppo_maze"
    """rllib module both arms start from (train_maze_agent.py --init-from)"""
    env_steps: int = 200_000
    """env steps each arm trains"""
    share: float = 0.25
    """--collection-share of the mixed arm"""
    seeds: tuple[int, ...] = (0, 1, 2)
    """training seeds, one training per arm each"""
    episodes: int = 20
    """episodes per level in every evaluation"""
    mazes: int = 100
    """random valid mazes in the random set"""
    jobs: int = 2
    """trainings and evaluations run side by side"""


def parse_args(argv: list[str] | None = None) -> Args:
    """``Args`` from the command line (``--help`` lists every flag)."""
    return tyro.cli(Args, args=argv, description=__doc__.split("\n\n")[0])


# ------------------------------------------------------------------------------------------- 1. train

def run_name(arm: str, seed: int) -> str:
    return f"{arm}_s{seed}"


def trained(out: Path, name: str, env_steps: int) -> bool:
    progress = out / "tb_logs" / name / "progress.json"
    return progress.is_file() and json.loads(progress.read_text())["env_steps"] >= env_steps


def train_command(args: Args, arm: str, seed: int) -> list[str]:
    command = [sys.executable, str(TRAIN_SCRIPT), "--run-name", run_name(arm, seed), "--seed", str(seed),
               "--init-from", args.init_from, "--curriculum-steps", "0", "--total-env-steps", str(args.env_steps),
               "--eval-every", "0"]
    if arm == "mixed":
        command += ["--train-on-collection", str(Path(args.collection).resolve()),
                    "--collection-share", str(args.share)]
    return command


def train_all(args: Args, out: Path) -> None:
    """Runs the missing trainings, ``--jobs`` at a time (each one is a process with its own Ray)."""
    pending = [(arm, seed) for seed in args.seeds for arm in ARMS
               if not trained(out, run_name(arm, seed), args.env_steps)]
    running: list[tuple[str, subprocess.Popen, float]] = []
    while pending or running:
        while pending and len(running) < args.jobs:
            arm, seed = pending.pop(0)
            name = run_name(arm, seed)
            log = (out / f"{name}.log").open("w")
            resume = ["--resume"] if (out / "tb_logs" / name / "checkpoint").exists() else []
            running.append((name, subprocess.Popen(train_command(args, arm, seed) + resume, cwd=out, stdout=log,
                                                   stderr=subprocess.STDOUT), time.perf_counter()))
            print(f"training {name} ...", flush=True)
        time.sleep(2)
        for entry in list(running):
            name, process, started = entry
            if process.poll() is not None:
                running.remove(entry)
                if process.returncode != 0:
                    raise SystemExit(f"training {name} failed (exit {process.returncode}); see {out / name}.log")
                print(f"trained {name} in {(time.perf_counter() - started) / 60:.1f} min", flush=True)


# ---------------------------------------------------------------------------------------- 2. evaluate

def train_script():
    """``experiments/train_maze_agent.py`` as a module: its run folders and its rule for collection folders."""
    if str(TRAIN_SCRIPT.parent) not in sys.path:
        sys.path.insert(0, str(TRAIN_SCRIPT.parent))
    import train_maze_agent

    return train_maze_agent


def test_sets(args: Args) -> tuple[dict[str, list[tuple[str, int]]], list[int]]:
    """``set name -> [(layout text, seed)]`` of the shown, unseen and random levels (module docstring), and the
    indices into the shown set of the levels the audit of ``--collection`` never saw solved."""
    from dsage_ray.domains.maze.generator import random_valid_levels
    from dsage_ray.domains.maze.layout import format_layout, load_layout

    load = train_script().load_audit_collection
    trained_on = load(args.collection, name=f"--collection {args.collection}").levels
    shown = [(format_layout(load_layout(level.level_path)), level.seed) for level in trained_on]
    shown_never = [index for index, level in enumerate(trained_on) if level.success_rate == 0.0]
    seen = {text for text, _ in shown}
    unseen = [(text, level.seed) for level in load(args.fresh, name=f"--fresh {args.fresh}").levels
              if level.success_rate == 0.0
              for text in [format_layout(load_layout(level.level_path))] if text not in seen]
    random = [(format_layout(level), index) for index, level in enumerate(random_valid_levels(args.mazes, seed=2022))]
    return {"shown": shown, "unseen": unseen, "random": random}, shown_never


def success_rates(spec: str, levels: list[tuple[str, int]], episodes: int) -> list[float]:
    """``spec``'s success rate on each level, evaluated with the level's seed (runs in a worker process)."""
    import torch

    from dsage_ray.domains.maze.agents import load_maze_agent
    from dsage_ray.domains.maze import evaluate
    from dsage_ray.domains.maze.layout import parse_layout

    torch.set_num_threads(1)
    agent = load_maze_agent(spec)
    return [float(evaluate(parse_layout(text), agent, episodes=episodes, seed=seed).success_rate)
            for text, seed in levels]


def evaluation_key(args: Args, sets: dict[str, list[tuple[str, int]]]) -> str:
    """What an earlier ``results.json`` must share for its evaluations to be reused: the levels, seeds and
    episodes of every set, the starting module and the trainings' settings."""
    import hashlib

    digest = hashlib.sha256(json.dumps([sets, args.episodes, args.init_from, args.env_steps, args.share]).encode())
    return digest.hexdigest()


def evaluate_all(args: Args, out: Path, sets: dict[str, list[tuple[str, int]]]) -> dict[str, dict]:
    """``agent name -> set name -> per-level success rates``, for the starting module and every training
    (reusing those of an earlier ``results.json`` with the same :func:`evaluation_key`)."""
    module_dir = train_script().module_dir
    agents = {"start": f"rllib:{args.init_from}"} | {
        run_name(arm, seed): f"rllib:{module_dir(out / 'tb_logs' / run_name(arm, seed) / 'checkpoint')}"
        for seed in args.seeds for arm in ARMS}
    results: dict[str, dict] = {name: {} for name in agents}
    earlier = out / "results.json"
    if earlier.is_file():
        data = json.loads(earlier.read_text())
        if data.get("evaluation_key") == evaluation_key(args, sets):
            for name in agents:
                results[name].update(data["results"].get(name, {}))
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = {(name, set_name): pool.submit(success_rates, spec, sets[set_name], args.episodes)
                   for name, spec in agents.items() for set_name in SETS if set_name not in results[name]}
        for (name, set_name), future in futures.items():
            results[name][set_name] = future.result()
            print(f"  {name:10s} {set_name:7s} success {np.mean(results[name][set_name]):.3f}", flush=True)
    return results


# ------------------------------------------------------------------------------------------- 3. print

def mean_se(values: list[float]) -> tuple[float, float]:
    values = np.asarray(values, dtype=float)
    se = float(values.std(ddof=1) / np.sqrt(len(values))) if len(values) > 1 else float("nan")
    return float(values.mean()), se


def summary_table(args: Args, sets: dict[str, list], results: dict[str, dict],
                  shown_never: list[int]) -> str:
    """The markdown table: one row per arm and the paired difference, one column per test set (and one for
    the shown levels at ``shown_never``, those the audit never saw solved)."""
    def cell(values: list[float]) -> str:
        mean, se = mean_se(values)
        return f"{mean:.3f}" if np.isnan(se) else f"{mean:.3f} ± {se:.3f}"

    columns = {f"shown ({len(sets['shown'])} levels)": ("shown", None),
               f"shown, never solved ({len(shown_never)})": ("shown", shown_never),
               f"unseen, never solved ({len(sets['unseen'])})": ("unseen", None),
               f"random ({len(sets['random'])} mazes)": ("random", None)}

    def score(name: str, column: tuple[str, list[int] | None]) -> float:
        rates = np.asarray(results[name][column[0]])
        return float(np.mean(rates if column[1] is None else rates[column[1]]))

    per_seed = {arm: {title: [score(run_name(arm, seed), column) for seed in args.seeds]
                      for title, column in columns.items()} for arm in ARMS}
    lines = [f"| agent | {' | '.join(columns)} |", "|---|" + "---|" * len(columns),
             f"| start (`{args.init_from}`) | " + " | ".join(cell([score("start", c)]) for c in columns.values()) + " |"]
    lines += [f"| {arm} | " + " | ".join(cell(per_seed[arm][title]) for title in columns) + " |" for arm in ARMS]
    lines.append("| mixed - plain (paired by seed) | " + " | ".join(
        cell(list(np.subtract(per_seed["mixed"][title], per_seed["plain"][title]))) for title in columns) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from dsage_ray.errors import InputError

    try:
        sets, shown_never = test_sets(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    print(f"test sets: {', '.join(f'{name} {len(levels)} levels' for name, levels in sets.items())}", flush=True)
    if not sets["unseen"]:
        raise SystemExit(f"--fresh {args.fresh}: no never-solved level that --collection lacks; audit with a larger "
                         f"budget or another seed")
    train_all(args, out)
    results = evaluate_all(args, out, sets)
    table = summary_table(args, sets, results, shown_never)
    record = {"args": dataclasses.asdict(args), "evaluation_key": evaluation_key(args, sets), "results": results}
    (out / "results.json").write_text(json.dumps(record, indent=1))
    caption = (f"Continued from `{args.init_from}` for {args.env_steps:,} env steps, seeds "
               f"{', '.join(map(str, args.seeds))}; mixed: share {args.share} of the episodes on the levels of "
               f"`{args.collection}`; {args.episodes} episodes per level, the same seeds for every agent; success "
               f"rate, mean ± standard error over seeds.")
    (out / "summary.md").write_text(table + "\n\n" + caption + "\n")
    print()
    print(table)
    print()
    print(caption)
    print(f"results: {out / 'results.json'}\nsummary: {out / 'summary.md'}\n"
          f"trainings in TensorBoard: tensorboard --logdir {out / 'tb_logs'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
