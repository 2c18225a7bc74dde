"""Plays every RL Zoo run folder under a root on its nominal environment and prints its return beside the zoo's own.

The check that ``sb3:FOLDER`` plays the zoo's agents as they were trained, on folders the tests never saw::

    python benchmarks/zoo_nominal.py ../shared/models/rl_zoo --episodes 10
    python benchmarks/zoo_nominal.py /tmp/rl-trained-agents --episodes 5 --only ppo,sac

Each row: the folder, the environment played (the zoo's id, moved to the version Gymnasium registers: LunarLander-v2
as LunarLander-v3, LunarLanderContinuous-v2 as LunarLander-v3 with ``continuous=True``), the zoo's last evaluation
(``evaluations.npz``), the mean ± s.e. of ``--episodes`` deterministic episodes here, and what the loader applied
(normalisation, frame stacking, wrappers). A folder that does not load prints its one-line reason.
"""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.spaces import stack_observations
from dsage_ray.agents import load_agent

#: Zoo ids whose version Gymnasium moved on: ``zoo id: (Gymnasium id, gym.make keywords)``.
RENAMED = {"LunarLander-v2": ("LunarLander-v3", {}), "LunarLanderContinuous-v2": ("LunarLander-v3", {"continuous": True}),
           "BipedalWalkerHardcore-v3": ("BipedalWalker-v3", {"hardcore": True})}


def nominal_env(zoo_id: str) -> tuple[str, dict]:
    return RENAMED.get(zoo_id, (zoo_id, {}))


def play(agent, env_id: str, kwargs: dict, *, episodes: int, seed: int) -> np.ndarray:
    """Episodes side by side on the registered environment, as the gym simulator plays them."""
    envs = [agent.wrap_env(gym.make(env_id, **kwargs)) for _ in range(episodes)]
    obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(envs)]
    returns, active, state = np.zeros(episodes), np.arange(episodes), agent.initial_state(episodes)
    rng = np.random.default_rng(seed)
    while len(active):
        actions, state = agent.act(stack_observations([obs[i] for i in active], envs[0].observation_space), state, rng)
        keep = []
        for row, i in enumerate(active):
            obs[i], reward, terminated, truncated, _ = envs[i].step(actions[row])
            returns[i] += reward
            if not (terminated or truncated):
                keep.append(row)
        if keep:
            state = agent.select_state(state, np.array(keep))
        active = active[keep]
    return returns


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="a folder of ALGO/ENV_1 zoo run folders")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--only", default="", help="comma-separated algorithms (folder names) to play")
    args = parser.parse_args()
    folders = sorted(p for p in args.root.glob("*/*_*") if p.is_dir() and any(p.glob("*/config.yml")))
    if args.only:
        folders = [p for p in folders if p.parent.name in args.only.split(",")]
    print(f"| folder | played on | zoo's last evaluation | here ({args.episodes} episodes) | applied |")
    print("|---|---|---|---|---|")
    for folder in folders:
        zoo_id = re.sub(r"_\d+$", "", folder.name)
        env_id, kwargs = nominal_env(zoo_id)
        played_on = env_id + "".join(f" {k}={v}" for k, v in kwargs.items())
        started = time.perf_counter()
        try:
            env = gym.make(env_id, **kwargs)
            agent = load_agent(f"sb3:{folder}", observation_space=env.observation_space,
                                   action_space=env.action_space, env=env)
            returns = play(agent, env_id, kwargs, episodes=args.episodes, seed=args.seed)
        except (AgentError, gym.error.Error, ImportError) as exc:
            print(f"| {folder.parent.name}/{folder.name} | {played_on} | | not played: {exc} | |")
            continue
        applied = ", ".join(filter(None, [
            "VecNormalize" if agent.normalization else "",
            f"{agent.frame_stack.n} frames" if agent.frame_stack else "",
            f"{len(agent.env_wrappers)} wrapper(s)" if agent.env_wrappers else ""])) or "none"
        spread = returns.std(ddof=1) / np.sqrt(len(returns)) if len(returns) > 1 else 0.0
        print(f"| {folder.parent.name}/{folder.name} | {played_on} | {agent.expected_return:.1f} | "
              f"{returns.mean():.1f} ± {spread:.1f} | {applied} ({time.perf_counter() - started:.0f} s) |")


if __name__ == "__main__":
    main()
