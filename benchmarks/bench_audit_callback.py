"""What auditing during training costs: the project's PPO training with and without ``AuditCallback``.

Trains the Maze agent of ``experiments/train_maze_agent.py`` (its config, curriculum and seed) for
``--iterations`` iterations in one process and one Ray instance (``--num-cpus``, default the script's 2):
without the callback, then with it, audits in the background (the default: a Ray actor with a CPU of its own),
and with ``--foreground`` also with audits in the training process. Every audited run writes a fresh series
(``--audit-every``, ``--audit-budget``). Background audits run in another process and foreground audits put
the global random states back, so every run trains the same policy (the script checks the returns match)
and the difference in wall time is the audits'. It prints

* each run's training wall time (the ``algo.train()`` calls, callbacks included; the algorithm's build is not
  counted), how long training waited for audits (saving the module; foreground: the audit too), how many
  audits ended and how many were skipped because the previous one still ran, and how long after the last
  iteration the last background audit ended;
* **overhead**: an audited run's extra training wall time over the plain run's, as a share of the plain
  run's;
* for foreground audits, the **projected overhead at the default** ``audit_every``: the mean audit time over
  ``DEFAULT_AUDIT_EVERY`` plain iterations (an audit's cost depends on the agent, not on how often it runs;
  early, weak agents run every episode to the step limit and are the dearest to audit).

Usage::

    nice -n 10 python benchmarks/bench_audit_callback.py                       # the defaults, 2 audits
    nice -n 10 python benchmarks/bench_audit_callback.py --iterations 20 --audit-every 10 --foreground
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def load_training_script():
    spec = importlib.util.spec_from_file_location("train_maze_agent", REPO_ROOT / "experiments" / "train_maze_agent.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # tyro resolves the Args annotations there
    spec.loader.exec_module(module)
    return module


def train(script, args, iterations: int, *, audit_dir: Path | None = None, background: bool = True,
          audit_every: int = 0, audit_budget: int = 0) -> dict:
    """``iterations`` PPO iterations; their wall times and returns, and the audits' waits and records."""
    from dsage_ray.integrations.rllib import AuditCallback, finish_audits

    config = script.build_config(args)
    if audit_dir is not None:
        config.callbacks(AuditCallback.configured(audit_every=audit_every, audit_budget=audit_budget,
                                                  out_dir=audit_dir, seed=args.seed, background=background))
    algo = config.build_algo()
    steps, seconds, returns, tail = 0, [], [], 0.0
    try:
        for _ in range(iterations):
            script.set_difficulty(algo, script.difficulty_at(steps, args))
            started = time.perf_counter()
            result = algo.train()
            seconds.append(time.perf_counter() - started)
            steps += int(result["env_runners"]["num_env_steps_sampled"])
            returns.append(result["env_runners"].get("episode_return_mean"))
        started = time.perf_counter()
        finish_audits(algo)
        tail = time.perf_counter() - started
        callbacks = algo.callbacks if isinstance(algo.callbacks, list) else [algo.callbacks]
        audits = [a for cb in callbacks if isinstance(cb, AuditCallback) for a in cb.audits]
    finally:
        algo.stop()
    return {"seconds": seconds, "returns": returns, "steps": steps, "audits": audits, "tail": tail}


def describe_record(record) -> str:
    if record is None:
        return "skipped (see the warning above)"
    numbers = record.scalars()
    success = "-" if record.suite_success_rate is None else f"{record.suite_success_rate:.2f}"
    return (f"{record.wall_time:5.1f} s in the audit; suite {record.suite_size} levels, success {success}, new "
            f"failures {record.new_failures}, never solved {numbers.get('audit/never_solved', float('nan')):.0f}"
            + (f"; error: {record.error}" if record.error else ""))


def main() -> int:
    from dsage_ray.integrations import DEFAULT_AUDIT_BUDGET, DEFAULT_AUDIT_EVERY

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--audit-every", type=int, default=DEFAULT_AUDIT_EVERY, help="iterations between audits")
    parser.add_argument("--audit-budget", type=int, default=DEFAULT_AUDIT_BUDGET, help="evaluations per audit search")
    parser.add_argument("--iterations", type=int, default=0, help="training iterations (default 2 x --audit-every)")
    parser.add_argument("--foreground", action="store_true", help="also measure audits in the training process")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--train-batch-size", type=int, default=0, help="env steps per iteration (default: the script's)")
    parser.add_argument("--num-cpus", type=int, default=0, help="CPUs of the Ray instance (default: the script's)")
    parser.add_argument("--out", default="", help="where the audited runs' folders go (default: a temporary folder)")
    options = parser.parse_args()
    iterations = options.iterations or 2 * options.audit_every

    import ray
    import torch

    from dsage_ray.ray.session import start_ray

    script = load_training_script()
    argv = ["--seed", str(options.seed)]
    if options.train_batch_size:
        argv += ["--train-batch-size", str(options.train_batch_size)]
    if options.num_cpus:
        argv += ["--num-cpus", str(options.num_cpus)]
    args = script.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    start_ray(num_cpus=args.num_cpus, log_to_driver=False)
    out = Path(options.out) if options.out else Path(tempfile.mkdtemp(prefix="bench_audit_callback."))
    audit = dict(audit_every=options.audit_every, audit_budget=options.audit_budget)
    load_before = os.getloadavg()[0]
    try:
        runs = {"without the callback": train(script, args, iterations)}
        runs["audits in the background"] = train(script, args, iterations, audit_dir=(out / "background").resolve(),
                                                 background=True, **audit)
        if options.foreground:
            runs["audits in the training process"] = train(
                script, args, iterations, audit_dir=(out / "foreground").resolve(), background=False, **audit)
    finally:
        ray.shutdown()

    plain = runs["without the callback"]
    plain_s, per_iteration = sum(plain["seconds"]), statistics.mean(plain["seconds"])
    due = iterations // options.audit_every
    print(f"PPO, {args.train_batch_size} env steps per iteration, seed {options.seed}, {iterations} iterations, "
          f"Ray with {args.num_cpus} CPUs; audit every {options.audit_every} iterations ({due} due), "
          f"audit budget {options.audit_budget} evaluations; load average {load_before:.1f} before, "
          f"{os.getloadavg()[0]:.1f} after")
    for name, run in runs.items():
        total = sum(run["seconds"])
        line = f"  {name:<32} {total:7.1f} s training ({run['steps']} env steps)"
        if name != "without the callback":
            waited = sum(w for _, _, w in run["audits"])
            ended = sum(r is not None for _, r, _ in run["audits"])
            line += (f", +{(total - plain_s) / plain_s:.1%}; waited {waited:.1f} s for audits; {ended} audits ended, "
                     f"{due - len(run['audits'])} skipped")
            if run["tail"] > 0.5:
                line += f"; the last ended {run['tail']:.0f} s after training"
        print(line)
        for iteration, record, waited in run["audits"]:
            print(f"      audit of iteration {iteration:4d}: training waited {waited:5.1f} s; {describe_record(record)}")
        if name != "without the callback":
            print(f"      same training as without the callback: {'yes' if run['returns'] == plain['returns'] else 'NO'}")
    print(f"overhead (extra training wall time / training wall time without the callback), at this size:")
    for name, run in runs.items():
        if name != "without the callback":
            print(f"  {name}: {(sum(run['seconds']) - plain_s) / plain_s:.1%}")
    foreground = runs.get("audits in the training process")
    if foreground and foreground["audits"]:
        mean_audit = statistics.mean(w for _, _, w in foreground["audits"])
        print(f"projected overhead of audits in the training process every {DEFAULT_AUDIT_EVERY} iterations: "
              f"{mean_audit / (DEFAULT_AUDIT_EVERY * per_iteration):.1%} (mean audit {mean_audit:.1f} s over "
              f"{DEFAULT_AUDIT_EVERY} x {per_iteration:.2f} s of training)")
    print(f"series: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
