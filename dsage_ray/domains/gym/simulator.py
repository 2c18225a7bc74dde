"""Plays an agent on one level of a Gymnasium environment: the episodes run side by side, one batched action per step.

Each episode has its own environment instance (built with the level's ``gym.make`` keywords), reset with its
own seed (or the space's ``reset_seed``) and the level's reset options; then the level's attributes are set on
``env.unwrapped``, the space's derived attributes recomputed, where the space says so the first observation
re-read, and the space's setup hook called (user code, which may return a new first observation). The agent acts
on the observations of the episodes still running, so a neural policy costs one forward pass per step, not one per
episode. A space declared deterministic plays one episode per level: the others would repeat it.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from typing import Any, Mapping, Sequence

import numpy as np

from dsage_ray.domains.gym.readings import StepReadings, read_signal, signal_key
from dsage_ray.domains.gym.space import EnvSpace, Signal, SpaceError, evaluate_expression
from dsage_ray.memory import require_memory

_INDEXED = re.compile(r"^([A-Za-z_]\w*)\[(\d+)\]$")


@dataclasses.dataclass
class Episodes:
    """What the episodes of one evaluation did, one entry per episode.

    Attributes:
        returns, lengths, terminated, truncated, success: Per episode.
        signals: Each asked :class:`Signal`'s value per episode, keyed by :func:`signal_key`.
        occupancy: Steps per histogram bin, summed over the episodes and divided by ``episodes × step limit``
            (so it sums to the mean share of the step limit the episodes lasted).
    """

    returns: np.ndarray
    lengths: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    success: np.ndarray
    signals: dict[str, np.ndarray]
    occupancy: np.ndarray


def make_env(space: EnvSpace, values: Mapping[str, Any], *, render_mode: str | None = None):
    """The environment of one level: ``gym.make`` with the fixed keywords and the level's keyword parameters.

    Raises:
        SpaceError: An unknown environment id, or keywords the environment does not take (one line).
    """
    import gymnasium as gym

    from dsage_ray.domains.gym.envs import register

    register()
    kwargs = {**space.env_args, **{p.key: values[p.name] for p in space.params if p.target == "make"}}
    if space.max_episode_steps:
        kwargs["max_episode_steps"] = space.max_episode_steps
    if render_mode:
        kwargs["render_mode"] = render_mode
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # gymnasium warns about out-of-range physics parameters: that is the point
            return gym.make(space.env_id, **kwargs)
    except gym.error.Error as exc:  # NameNotFound, VersionNotFound, ... carry gymnasium's own did-you-mean
        raise SpaceError(f"environment {space.env_id!r}: {_first_line(exc)}") from None
    except TypeError as exc:
        raise SpaceError(f"environment {space.env_id!r} does not take these gym.make keywords "
                         f"{sorted(kwargs)}: {_first_line(exc)}") from None
    except ModuleNotFoundError as exc:
        raise SpaceError(f"environment {space.env_id!r} needs the module {exc.name!r}: install it "
                         f"(LunarLander: pip install 'dsage_ray[gym]')") from None


def reset_env(env, space: EnvSpace, values: Mapping[str, Any], *, seed: int) -> Any:
    """Resets ``env`` to the level (reset options, then attributes and derived attributes); the first observation.

    Raises:
        SpaceError: An attribute parameter the environment lacks, or a derived attribute that names one.
    """
    options = {p.key: values[p.name] for p in space.params if p.target == "reset"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        observation, _ = env.reset(seed=seed, options=options or None)
    unwrapped = env.unwrapped
    for p in space.params:
        if p.target == "attr":
            set_attribute(unwrapped, p.key, values[p.name], env_id=space.env_id)
    for name, expression in space.derived.items():
        try:
            value = evaluate_expression(expression, _Attributes(unwrapped))
        except KeyError as exc:
            raise SpaceError(f"environment {space.env_id!r}: derived attribute {name} = {expression!r} names "
                             f"{exc.args[0]!r}, which the environment lacks") from None
        except (ArithmeticError, ValueError, IndexError) as exc:
            raise SpaceError(f"environment {space.env_id!r}: derived attribute {name} = {expression!r} cannot be "
                             f"computed ({type(exc).__name__}: {exc})") from None
        if not np.isfinite(value):
            raise SpaceError(f"environment {space.env_id!r}: derived attribute {name} = {expression!r} is {value}")
        setattr(unwrapped, name, value)
    if space.observation_attr:
        if not hasattr(unwrapped, space.observation_attr):
            raise SpaceError(f"environment {space.env_id!r} has no attribute {space.observation_attr!r} "
                             f"(observation_attr)")
        observation = np.asarray(getattr(unwrapped, space.observation_attr),
                                 dtype=env.observation_space.dtype).reshape(env.observation_space.shape)
    if space.setup:
        from dsage_ray.domains.gym.setup_hook import call_setup

        returned = call_setup(space.setup, env, dict(values))
        if returned is not None:
            observation = _first_observation(returned, env, space)
    return observation


def _first_observation(observation: Any, env, space: EnvSpace) -> Any:
    """What a setup hook returned, checked against the observation space's shape (a Box's)."""
    shape = getattr(env.observation_space, "shape", None)
    if shape and np.shape(observation) != tuple(shape):
        raise SpaceError(f"[env] setup {space.setup!r} returned an observation of shape {np.shape(observation)}, "
                         f"not the environment's {tuple(shape)} (return the new first observation or None)")
    return observation


class _Attributes(Mapping):
    """An object's attributes as a read-only mapping, for derived-attribute expressions."""

    def __init__(self, obj: Any) -> None:
        self._obj = obj

    def __getitem__(self, name: str) -> Any:
        if name.startswith("_") or not hasattr(self._obj, name):
            raise KeyError(name)
        return getattr(self._obj, name)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and not name.startswith("_") and hasattr(self._obj, name)

    def __iter__(self):
        return iter(())

    def __len__(self) -> int:
        return 0


def set_attribute(obj: Any, key: str, value: Any, *, env_id: str) -> None:
    """Sets ``obj.key`` (``name[i]``: element ``i`` of the array attribute ``name``)."""
    match = _INDEXED.match(key)
    name = match.group(1) if match else key
    if name.startswith("_") or not hasattr(obj, name):
        public = sorted(a for a in vars(obj) if not a.startswith("_")) if hasattr(obj, "__dict__") else []
        raise SpaceError(f"environment {env_id!r} has no attribute {name!r} to set (its attributes: "
                         f"{', '.join(public[:25])})")
    if not match:
        setattr(obj, name, value)
        return
    array = getattr(obj, name)
    index = int(match.group(2))
    try:
        array = np.array(array, copy=True)
        array[index] = value
    except (IndexError, TypeError, ValueError) as exc:
        raise SpaceError(f"environment {env_id!r}: cannot set {key} ({_first_line(exc)})") from None
    setattr(obj, name, array)


def step_limit(env, space: EnvSpace) -> int:
    """The episode's step limit: the space's ``max_episode_steps``, else the environment's registered one.

    Raises:
        SpaceError: Neither is set (an episode could last for ever).
    """
    limit = space.max_episode_steps or (env.spec.max_episode_steps if env.spec is not None else None)
    if not limit:
        raise SpaceError(f"environment {space.env_id!r} has no step limit: set [env] max_episode_steps in the space")
    return int(limit)


#: A floor on the memory one running episode takes (its environment, observation and record); a Box2D or MuJoCo
#: environment takes more, so this only turns an absurd ``episodes`` into one line instead of an out-of-memory kill.
EPISODE_BYTES = 64_000


def check_episode_memory(episodes: int) -> None:
    """Raises ResourceError when ``episodes`` side by side would clearly not fit in memory."""
    require_memory(episodes * EPISODE_BYTES, what=f"{episodes:,} episodes side by side",
                   key="gym.episodes (--episodes)")


def run_episodes(space: EnvSpace, agent, values: Mapping[str, Any], *, seed: int, episodes: int,
                 signals: Sequence[Signal] = ()) -> Episodes:
    """Plays ``agent`` for ``episodes`` episodes of the level ``values``; deterministic for ``seed``.

    Args:
        space: The parameter space.
        agent: A batched :class:`~dsage_ray.agents.base.Agent` of this environment's spaces.
        values: ``{parameter name: value}`` of the level.
        seed: Draws each episode's reset seed (unless the space fixes one) and the agent's random numbers.
        episodes: Episodes played side by side; a space declared deterministic plays one.
        signals: Per-episode values to record beside the episode statistics (measures' and occupancy's).

    Raises:
        SpaceError: A missing ``info`` key or observation entry, named.
    """
    from dsage_ray.agents.spaces import stack_observations

    episodes = 1 if space.deterministic else episodes
    check_episode_memory(episodes)
    seeds = np.random.SeedSequence(seed).spawn(2)
    reset_seeds = ([space.reset_seed] * episodes if space.reset_seed is not None
                   else seeds[0].generate_state(episodes).tolist())
    rng = np.random.default_rng(seeds[1])
    envs = [agent.wrap_env(make_env(space, values)) for _ in range(episodes)]  # as the agent was trained
    try:
        limit = step_limit(envs[0], space)
        observations = [reset_env(env, space, values, seed=s) for env, s in zip(envs, reset_seeds)]
        readings = StepReadings(signals, episodes=episodes, env_id=space.env_id)
        returns, lengths = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
        terminated, truncated = np.zeros(episodes, bool), np.zeros(episodes, bool)
        success = np.zeros(episodes, bool)
        occupancy = np.zeros(space.occupancy_shape, dtype=np.float64)
        active = np.arange(episodes)
        state = agent.initial_state(episodes)
        while len(active):
            batch = stack_observations([observations[i] for i in active], envs[0].observation_space)
            actions, state = agent.act(batch, state, rng)
            finished = []
            for row, i in enumerate(active):
                observation, reward, term, trunc, info = envs[i].step(actions[row])
                observations[i] = observation
                returns[i] += float(reward)
                lengths[i] += 1
                readings.record(i, step=int(lengths[i]), observation=observation, reward=float(reward), info=info)
                if space.occupancy:
                    occupancy[_bin(space, observation, info)] += 1.0
                if term or trunc or lengths[i] >= limit:
                    terminated[i], truncated[i] = bool(term), not term
                    success[i] = _succeeded(space, reward=float(reward), episode_return=returns[i],
                                            length=int(lengths[i]), terminated=bool(term), info=info,
                                            observation=observation)
                    finished.append(row)
            if finished:
                keep = np.setdiff1d(np.arange(len(active)), finished)
                active = active[keep]
                if len(active):
                    state = agent.select_state(state, keep)
    finally:
        for env in envs:
            env.close()
    if not space.occupancy:
        occupancy[0, 0] = lengths.sum()
    occupancy /= episodes * limit
    recorded: dict[str, np.ndarray] = {}
    for s in signals:
        key = signal_key(s)
        if s.source in ("info", "obs"):
            recorded[key] = readings.values(s, lengths)
        elif s.source == "param":  # a choice counts as its index, as the measure's range does
            parameter = next(p for p in space.params if p.name == s.key)
            recorded[key] = np.full(episodes, float(parameter.numbers(parameter.unit(values[s.key]))))
        else:
            recorded[key] = {"return": returns, "length": lengths, "terminated": terminated,
                             "truncated": truncated}[s.source].astype(np.float64)
    return Episodes(returns=returns, lengths=lengths, terminated=terminated, truncated=truncated, success=success,
                    signals=recorded, occupancy=occupancy.astype(np.float32))


def _succeeded(space: EnvSpace, *, reward: float, episode_return: float, length: int, terminated: bool,
               info: Mapping[str, Any], observation: Any) -> bool:
    """Whether an episode that ended so succeeded: it is no fault, where the space declares one, else it passes
    the success test."""
    if space.fault is not None:
        return not space.fault.happened(last_reward=reward, episode_return=episode_return, length=length,
                                        terminated=terminated, truncated=not terminated, info=info,
                                        observation=observation)
    if space.success.info_key:
        return bool(info.get(space.success.info_key, False))
    return episode_return >= space.success.return_at_least


def _bin(space: EnvSpace, observation: Any, info: Mapping[str, Any]) -> tuple[int, int]:
    cells = []
    for coordinate, bins in zip(space.occupancy, space.bins):
        try:
            value = read_signal(coordinate.signal, observation, info)
        except (KeyError, IndexError):
            raise SpaceError(f"environment {space.env_id!r}: occupancy coordinate {coordinate.signal.describe()} "
                             f"is not there") from None
        share = (value - coordinate.low) / (coordinate.high - coordinate.low)
        cells.append(int(np.clip(np.floor(share * bins), 0, bins - 1)) if np.isfinite(share) else 0)
    return cells[0], cells[1]


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__
