"""Mario random latents at several σ: how human-like and how diverse the levels they decode to are.

DSAGE's ``n_rand`` initial solutions and DR's whole budget are latents from N(0, σ²)
(``mario.latent_sigma``; the authors' 0.2). Which σ suits the shipped generator is a property of
that generator, so this measures it: per σ, ``--levels`` latents (seed 0) decoded by the shipped
generator, their tile-histogram L1 distance to the human windows, how many distinct levels and
sky-tile columns of the 150×100 archive they reach, and for the first ``--played`` of them the
deterministic A* agent (one run each): completion, jumps, and distinct archive cells.

    python benchmarks/bench_latent_sigma.py [--sigmas 0.2,1.0] [--levels 200] [--played 30]
"""

from __future__ import annotations

import argparse
import json
import time


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sigmas", default="0.2,1.0", help="comma-separated latent standard deviations")
    parser.add_argument("--levels", type=int, default=200, help="latents decoded per σ")
    parser.add_argument("--played", type=int, default=30, help="of those, levels the A* agent plays once")
    args = parser.parse_args(argv)

    import numpy as np
    import torch

    torch.set_num_threads(1)
    from dsage_ray.domains.mario.domain import MarioDomain
    from dsage_ray.domains.mario.human_levels import human_windows
    from dsage_ray.domains.mario.plugin import MarioConfig
    from dsage_ray.domains.mario.tiles import NUM_TILES

    def tile_histogram(levels: np.ndarray) -> np.ndarray:
        return np.bincount(levels.ravel(), minlength=NUM_TILES) / levels.size

    human = tile_histogram(human_windows())
    report: dict = {"levels": args.levels, "played": args.played}
    for sigma in (float(s) for s in args.sigmas.split(",")):
        domain = MarioDomain(config=MarioConfig(runs=1, latent_sigma=sigma))
        latents = domain.random_solutions(args.levels, np.random.default_rng(0))
        levels = domain.levels(latents)
        sky_tiles = np.count_nonzero(levels[:, :9], axis=(1, 2))
        t0 = time.perf_counter()
        results = [domain.evaluate(z, seed=0) for z in latents[:args.played]]
        ok = [r for r in results if not r.failed]
        cells = {(int(r.measures[0]), int(r.measures[1])) for r in ok}  # 1-wide cells over [0,150]×[0,100]
        report[f"sigma={sigma:g}"] = row = {
            "tile_histogram_l1_vs_human": round(float(np.abs(tile_histogram(levels) - human).sum()), 3),
            "distinct_levels": int(len(np.unique(levels.reshape(len(levels), -1), axis=0))),
            "distinct_sky_tile_values": int(len(np.unique(sky_tiles))),
            "sky_tiles_mean_sd": [round(float(sky_tiles.mean()), 1), round(float(sky_tiles.std()), 1)],
            "played_mean_completion": round(float(np.mean([r.objective for r in ok])), 3),
            "played_mean_jumps": round(float(np.mean([r.measures[1] for r in ok])), 2),
            "played_distinct_cells": len(cells),
            "played_failed": len(results) - len(ok),
            "played_wall_s": round(time.perf_counter() - t0, 1),
        }
        print(json.dumps({f"sigma={sigma:g}": row}), flush=True)
    return report


if __name__ == "__main__":
    main()
