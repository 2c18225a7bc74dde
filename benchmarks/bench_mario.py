"""Mario domain throughput: JVM start, GAN levels per second, A* episodes per second per core.

Episodes use the deterministic A* budget (``MarioConfig`` defaults: 1,000 iterations per tick,
timer 20 = 666 ticks, small Mario) on a fixed set of generated levels (latent seed 0), one
episode per level, in this single process. Java runs the agent on one thread, so episodes per
second of wall clock is the per-core rate when the core is free; on a shared machine the rate
per CPU-second of this process is the steadier number, and both are printed.

    python benchmarks/bench_mario.py [--levels 20] [--astar-iterations 1000] [--json]
    python benchmarks/bench_mario.py --completion-share 50   # A* on GAN levels vs human windows
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import resource
import statistics
import time


def cpu_seconds() -> float:
    """CPU time of this process including the JVM's threads (JIT, GC)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--levels", type=int, default=20, help="generated levels, one episode each")
    parser.add_argument("--astar-iterations", type=int, default=1000)
    parser.add_argument("--timer", type=int, default=20)
    parser.add_argument("--gan-batch", type=int, default=256)
    parser.add_argument("--gan-levels", type=int, default=1024)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--completion-share", type=int, default=0, metavar="N",
                        help="instead: share of N generated levels (latent seed 1) and of N evenly spaced "
                             "human windows that the A* agent completes")
    parser.add_argument("--sets", default="generated,human", help="with --completion-share: which level sets")
    args = parser.parse_args(argv)
    if args.completion_share:
        return completion_share(args)

    import numpy as np
    import torch

    torch.set_num_threads(1)  # per-core figures
    from dsage_ray.domains.mario.generator import latents_to_levels, load_generator
    from dsage_ray.domains.mario.simulator import MarioSimulator, java

    report: dict = {"pid": os.getpid(), "cpu_count": os.cpu_count(), "load_avg_1m": os.getloadavg()[0]}

    # --- JVM start (classpath, compiled timer class; the compile is cached after the first run).
    t0 = time.perf_counter()
    handles = java()
    report["jvm_start_s"] = round(handles.jvm_start_s, 3)
    report["jvm_ready_s"] = round(time.perf_counter() - t0, 3)
    report["deterministic_timer"] = handles.DeterministicTimer is not None

    # --- GAN throughput.
    generator = load_generator("builtin")
    z = np.random.default_rng(0).standard_normal((args.gan_levels, 32)).astype(np.float32)
    latents_to_levels(generator, z[: args.gan_batch], batch_size=args.gan_batch)  # warm-up
    t0 = time.perf_counter()
    latents_to_levels(generator, z, batch_size=args.gan_batch)
    gan_s = time.perf_counter() - t0
    report["gan_levels_per_s_1_thread"] = round(args.gan_levels / gan_s, 1)
    t0 = time.perf_counter()
    for i in range(32):
        latents_to_levels(generator, z[i:i + 1])
    report["gan_single_level_ms"] = round(1000 * (time.perf_counter() - t0) / 32, 2)

    # --- Episodes on a fixed set of generated levels.
    levels = latents_to_levels(generator, np.random.default_rng(0).standard_normal((args.levels, 32)))
    simulator = MarioSimulator(timer=args.timer, astar_iterations=args.astar_iterations)
    flat = np.zeros((16, 30), dtype=np.int64)
    flat[14:] = 11  # ground: one JIT warm-up episode, not timed
    simulator.play(flat)
    walls, ticks, statuses, completion = [], [], collections.Counter(), []
    c0, t0 = cpu_seconds(), time.perf_counter()
    for level in levels:
        episode = simulator.play(level)
        walls.append(episode.wall_s)
        ticks.append(episode.ticks)
        statuses[episode.status] += 1
        completion.append(episode.completion)
    wall = time.perf_counter() - t0
    cpu = cpu_seconds() - c0
    report.update({
        "episodes": args.levels,
        "astar_iterations": args.astar_iterations,
        "timer": args.timer,
        "episodes_wall_s": round(wall, 2),
        "episodes_cpu_s": round(cpu, 2),
        "episodes_per_s_wall": round(args.levels / wall, 3),
        "episodes_per_cpu_s": round(args.levels / cpu, 3),
        "episode_s_median": round(statistics.median(walls), 3),
        "episode_s_max": round(max(walls), 3),
        "ticks_median": statistics.median(ticks),
        "ms_per_tick": round(1000 * wall / max(sum(ticks), 1), 3),
        "status": dict(statuses),
        "completed_share": round(statuses.get("WIN", 0) / args.levels, 3),
        "mean_completion": round(float(np.nanmean(completion)), 3),
        "load_avg_1m_after": os.getloadavg()[0],
    })
    if args.json:
        print(json.dumps(report))
    else:
        for key, value in report.items():
            print(f"{key:28s} {value}")
    return report


def completion_share(args: argparse.Namespace) -> dict:
    """A* completion on generated levels next to human-authored windows of the same size."""
    import numpy as np

    from dsage_ray.domains.mario.generator import latents_to_levels, load_generator
    from dsage_ray.domains.mario.human_levels import human_windows
    from dsage_ray.domains.mario.simulator import MarioSimulator

    n = args.completion_share
    wanted = args.sets.split(",")
    sets = {}
    if "generated" in wanted:
        sets["generated"] = latents_to_levels(load_generator("builtin"), np.random.default_rng(1).standard_normal((n, 32)))
    if "human" in wanted:
        windows = human_windows()
        sets["human"] = windows[np.linspace(0, len(windows) - 1, n).round().astype(int)]
    simulator = MarioSimulator(timer=args.timer, astar_iterations=args.astar_iterations)
    report: dict = {"n": n, "astar_iterations": args.astar_iterations, "timer": args.timer}
    for name, levels in sets.items():
        t0 = time.perf_counter()
        episodes = [simulator.play(level) for level in levels]
        statuses = collections.Counter(e.status for e in episodes)
        finished = [e for e in episodes if e.ok]  # wall-clock timeouts (a loaded machine) have no result
        report[name] = {
            "completed_share": round(statuses.get("WIN", 0) / n, 3),
            "completed_share_of_finished": round(statuses.get("WIN", 0) / max(len(finished), 1), 3),
            "mean_completion_of_finished": round(float(np.mean([e.completion for e in finished])), 3),
            "status": dict(statuses),
            "mean_jumps": round(float(np.mean([e.jumps for e in episodes])), 2),
            "mean_sky_tiles": round(float(np.mean([np.count_nonzero(lv[:9]) for lv in levels])), 1),
            "wall_s": round(time.perf_counter() - t0, 1),
        }
        print(json.dumps({name: report[name]}), flush=True)
    print(json.dumps(report))
    return report


if __name__ == "__main__":
    main()
