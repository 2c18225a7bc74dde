"""The Python API in one page: audit an agent, then run DSAGE itself, and read what came back.

    python examples/api_quickstart.py [OUT_DIR]        # about a minute on 2 cores; default tb_logs/api_quickstart

Both calls run in this process (``local=True``); leave it out to go through Ray Tune with the same result
for the same seed. The command line (``dsage-ray audit`` / ``dsage-ray run``) calls the same functions.
"""

from __future__ import annotations

import sys
from pathlib import Path

import dsage_ray


def main(out: Path) -> None:
    # 1. An audit: a DSAGE search for levels where the agent fails, then every level re-evaluated
    #    with a recorded seed. Here a random policy on a tiny budget; name yours as "dcd:PATH",
    #    "rllib:PATH" or "torchscript:PATH".
    collection = dsage_ray.run_audit(agent="builtin:random", preset="tiny", budget=60, local=True,
                                     out=out / "audit", overrides={"maze.episodes": 4})
    print(collection.summary_line)
    for level in collection.levels[:3]:
        print(f"level #{level.id}: success {level.success_rate:.2f} over {level.episodes} episodes, seed {level.seed}, "
              f"{level.level_path.name}")
    print(f"report: {collection.report_path}")

    # 2. A run: DSAGE (or the baseline the config's variant names) to its evaluation budget. The
    #    config comes from a file, a dict of dotted keys or a RunConfig, exactly as on the command line.
    result = dsage_ray.run("experiments/configs/maze_dsage.toml", preset="tiny", local=True, out=out / "run",
                           overrides={"maze.agent": "builtin:wall_follower", "budget": 60})
    final = result.metrics[-1]
    print(f"run: {final['evals']:.0f} evaluations, QD-score {final['qd_score']:.1f}, "
          f"{len(result.archive)} elites in the archive")
    print(f"checkpoint: {result.checkpoint}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("tb_logs/api_quickstart"))
