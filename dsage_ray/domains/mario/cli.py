"""``dsage-ray mario eval`` and ``dsage-ray mario sample``."""

from __future__ import annotations

import argparse

from dsage_ray.errors import InputError


def add_subparser(subparsers) -> None:
    """Registers ``mario`` (with ``eval`` and ``sample``) on the top-level CLI's sub-parsers."""
    mario = subparsers.add_parser("mario", help="Mario domain tools")
    commands = mario.add_subparsers(dest="mario_command", required=True)

    ev = commands.add_parser("eval", help="play the A* agent on a level file",
                             description="Plays Robin Baumgarten's A* agent on a 16-row level text file.")
    ev.add_argument("--level", required=True, metavar="FILE", help="level text: 16 rows of the 17 tile characters")
    ev.add_argument("--runs", type=int, default=5, help="episodes (default 5; 1 is played when deterministic)")
    ev.add_argument("--timer", type=int, default=20, help="game time in seconds (default 20 = 666 ticks)")
    ev.add_argument("--astar-iterations", type=int, default=1000,
                    help="A* iterations per tick; 0 = the stock 40 ms wall-clock timer (default 1000)")
    ev.add_argument("--large", action="store_true", help="start as large Mario (default: small)")
    ev.add_argument("--timeout", type=float, default=60.0, help="wall-clock seconds per episode (default 60)")
    ev.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    ev.add_argument("--render", metavar="OUT.png", help="also write a PNG with Mario's path")
    ev.set_defaults(handler=run_eval)

    sa = commands.add_parser("sample", help="write GAN levels (text + PNG) for random latents")
    sa.add_argument("--n", type=int, required=True, help="number of levels")
    sa.add_argument("--out", required=True, metavar="DIR", help="output folder")
    sa.add_argument("--seed", type=int, default=0, help="latent seed (default 0)")
    sa.add_argument("--generator", default="builtin", help="'builtin' or a weights file (default builtin)")
    sa.set_defaults(handler=run_sample)


def run_eval(args: argparse.Namespace) -> int:
    """Handler of ``mario eval``; bad input ends it through :func:`dsage_ray.cli.main` in one line."""
    from dsage_ray.domains.mario.evaluate import evaluate_level
    from dsage_ray.domains.mario.simulator import MarioSimulator
    from dsage_ray.domains.mario.tiles import load_level

    if args.runs < 1:
        raise InputError(f"--runs must be positive, got {args.runs}")
    level = load_level(args.level)
    simulator = MarioSimulator(timer=args.timer, astar_iterations=args.astar_iterations,
                               mario_state=1 if args.large else 0, episode_timeout_s=args.timeout)
    result = evaluate_level(level, simulator=simulator, runs=args.runs)
    if args.render:
        from dsage_ray.domains.mario.render import save_level_png

        save_level_png(level, args.render, path=result.episodes[0].path)
    if args.json:
        print(result.to_json())
    else:
        print(f"level           {args.level} ({level.shape[0]}x{level.shape[1]}, {result.sky_tiles} sky tiles)")
        print(f"runs            {result.runs} ({len(result.episodes)} played, "
              f"{'deterministic' if all(e.deterministic for e in result.episodes) else 'wall-clock timer'})")
        print(f"status          {', '.join(result.statuses)}")
        print(f"completion      {result.objective:.3f}  (per run: {', '.join(f'{c:.3f}' for c in result.completion)})")
        print(f"success rate    {result.success_rate:.3f}")
        print(f"mean jumps      {result.mean_jumps:.1f}")
        print(f"enemies killed  {result.enemies_killed:.1f}")
        if result.failed:
            print(f"error           {result.error}")
    return 1 if result.failed else 0


def run_sample(args: argparse.Namespace) -> int:
    """Handler of ``mario sample``: ``level_XXX.txt`` and ``level_XXX.png`` per latent, plus ``latents.npy``."""
    from pathlib import Path

    import numpy as np

    from dsage_ray.domains.mario.generator import latents_to_levels, load_generator
    from dsage_ray.domains.mario.render import save_level_png
    from dsage_ray.domains.mario.tiles import indices_to_string

    if args.n < 1:
        raise InputError(f"--n must be positive, got {args.n}")
    out = Path(args.out)
    generator = load_generator(args.generator)
    latents = np.random.default_rng(args.seed).standard_normal((args.n, generator.latent_dim)).astype(np.float32)
    levels = latents_to_levels(generator, latents)
    out.mkdir(parents=True, exist_ok=True)
    np.save(out / "latents.npy", latents)
    for i, level in enumerate(levels):
        (out / f"level_{i:03d}.txt").write_text(indices_to_string(level) + "\n")
        save_level_png(level, out / f"level_{i:03d}.png")
    print(f"wrote {args.n} levels to {out}")
    return 0
