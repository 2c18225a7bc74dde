"""Trains a tabular Q-learning agent on a TaxiMap map: held-back agents for the Taxi task (issue 62).

The peers' Taxi agent is one Q-table. A held-back check needs agents the comparison was never tuned on and that no
repository holds, so this script makes them: Q-learning (epsilon-greedy, a constant step size) on
``dsage_ray/TaxiMap-v0`` as Taxi trains, the episode going on after a crash or an illegal action
(``end_on_fault=False``), from Taxi's initial states. The transitions are read off the environment once (every
state, every action), and the learning loop runs in numba. The table is written where ``--out`` says (a run-time
file, never committed)::

    python benchmarks/train_taxi_qtable.py --map /tmp/taxi/map_large.txt --episodes 40000 --seed 1 \\
        --out /tmp/taxi/heldback_40k.npy
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numba
import numpy as np

from dsage_ray.domains.gym.envs.taxi_map import TaxiMapEnv


def transitions(env: TaxiMapEnv) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``next_state[s, a]``, ``reward[s, a]`` and ``done[s, a]`` of every state and action of ``env``."""
    n, k = env.observation_space.n, env.action_space.n
    next_state, reward, done = np.zeros((n, k), np.int64), np.zeros((n, k)), np.zeros((n, k), bool)
    for state in range(n):
        for action in range(k):
            env.set_state(state)
            next_state[state, action], reward[state, action], done[state, action], _, _ = env.step(action)
    return next_state, reward, done


def initial_states(env: TaxiMapEnv) -> np.ndarray:
    """Taxi's initial states: any cell, the passenger at a location, the destination another one."""
    count = len(env.locations)
    return np.array([env.encode(r, c, p, d) for r in range(env.rows) for c in range(env.columns)
                     for p in range(count) for d in range(count) if p != d], dtype=np.int64)


@numba.njit(cache=True)
def q_learning(next_state, reward, done, starts, episodes, max_steps, alpha, gamma, epsilon, seed):  # pragma: no cover
    """The table after ``episodes`` episodes of epsilon-greedy Q-learning over the transition arrays."""
    np.random.seed(seed)
    n, k = reward.shape
    table = np.zeros((n, k))
    for _ in range(episodes):
        state = starts[np.random.randint(len(starts))]
        for _ in range(max_steps):
            action = np.random.randint(k) if np.random.random() < epsilon else np.argmax(table[state])
            following = next_state[state, action]
            ended = done[state, action]
            target = reward[state, action] + (0.0 if ended else gamma * table[following].max())
            table[state, action] += alpha * (target - table[state, action])
            state = following
            if ended:
                break
    return table


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", required=True, help="the map drawing (e.g. their map_large.txt)")
    parser.add_argument("--episodes", type=int, default=40_000)
    parser.add_argument("--alpha", type=float, default=0.1)
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--epsilon", type=float, default=0.1)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    env = TaxiMapEnv(map_file=args.map, end_on_fault=False)
    tic = time.time()
    table = q_learning(*transitions(env), initial_states(env), args.episodes, 200, args.alpha, args.gamma,
                       args.epsilon, args.seed)
    np.save(args.out, table)
    print(f"{args.out}: Q-learning, {args.episodes:,} episodes of at most 200 steps (alpha {args.alpha}, gamma "
          f"{args.gamma}, epsilon {args.epsilon}, seed {args.seed}), {time.time() - tic:.0f} s")


if __name__ == "__main__":
    main()
