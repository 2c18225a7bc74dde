"""pyribs overhead per inner-loop iteration (ask + tell, no surrogate), SPEC §5 settings.

- MAP-Elites, 5 emitters × 30 (batch 150), Maze archive 256×162 with a 16×16 occupancy extra field.
- CMA-ME, 5 emitters × 30, Mario archive 150×100 over 32-d latents, same extra field.

The predictor is a cheap random stand-in (uniform measures over the whole archive), timed separately
and excluded. Usage: ``python benchmarks/bench_qd_overhead.py [--iterations N]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from dsage_ray.config import QDConfig
from dsage_ray.qd import make_archive, make_scheduler, run_inner_loop

OCCUPANCY = (16, 16)


def random_predictor(ranges, seed):
    rng = np.random.default_rng(seed)
    low, high = np.array(ranges, dtype=np.float64).T

    def predict(solutions):
        n = len(solutions)
        occupancy = rng.random((n, *OCCUPANCY), dtype=np.float32)
        return rng.random(n), rng.uniform(low, high, size=(n, len(low))), {"occupancy": occupancy}

    return predict


def bench(name, *, emitter, solution_dim, dims, ranges, solution_dtype, iterations, warmup=20):
    archive = make_archive(solution_dim=solution_dim, dims=dims, ranges=ranges, occupancy_shape=OCCUPANCY,
                           seed=0, solution_dtype=solution_dtype)
    config = QDConfig(emitter=emitter, num_emitters=5, batch_size=30)
    scheduler = make_scheduler(archive, config=config, solution_dim=solution_dim,
                               random_solutions=lambda n, rng: rng.integers(0, 2, (n, solution_dim)), seed=0)
    predict = random_predictor(ranges, seed=1)
    run_inner_loop(scheduler, predict, warmup)  # JIT compilation (numba in CMA-ES), first allocations
    t = run_inner_loop(scheduler, predict, iterations)
    print(f"{name:<42} {t.overhead_ms_per_iteration:6.2f} ms/iter "
          f"(ask {1e3 * t.ask_s / t.iterations:5.2f}, tell {1e3 * t.tell_s / t.iterations:5.2f}; "
          f"{len(archive)} elites after {warmup + iterations} iters)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=300)
    args = parser.parse_args()
    maze = dict(solution_dim=256, dims=(256, 162), ranges=[(0, 256), (0, 648)], iterations=args.iterations)
    bench("MAP-Elites 5x30, 256x162, int8 bitmaps", emitter="map_elites", solution_dtype=np.int8, **maze)
    bench("MAP-Elites 5x30, 256x162, float64 bitmaps", emitter="map_elites", solution_dtype=np.float64, **maze)
    bench("CMA-ME 5x30, 150x100, 32-d latents", emitter="cma_me", solution_dim=32, dims=(150, 100),
          ranges=[(0, 150), (0, 100)], solution_dtype=np.float64, iterations=args.iterations)


if __name__ == "__main__":
    main()
