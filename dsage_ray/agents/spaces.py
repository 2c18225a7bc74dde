"""Batches over Gymnasium spaces: how observations go into an :class:`~dsage_ray.agents.base.Agent` and actions out.

Batches (:func:`stack_observations`): a Box observation arrives as ``(n, *shape)`` in the space's dtype, a
Discrete one as int64 ``(n,)``, a Dict as a dict and a Tuple as a tuple of such arrays, any other space (Text,
MiniGrid's mission) as an object array of the ``n`` observations. Actions leave as a numpy array with ``n`` rows
(:func:`finish_actions`): int64 ``(n,)`` for Discrete, float32 ``(n, *shape)`` clipped to the bounds for a float
Box, int64 for MultiDiscrete, int8 for MultiBinary. Every draw comes from the caller's ``rng`` (never torch's), so
an evaluation is reproducible from its seed.
"""

from __future__ import annotations

import copy
from typing import Any, Callable

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, tree_map
from dsage_ray.agents.loader import describe_exception

#: How many sampled observations the load-time check feeds an agent.
CHECK_BATCH = 2


def stack_observations(observations: list, space: gymnasium.Space) -> Any:
    """Batches single observations of ``space`` into the input of :meth:`Agent.act` (module docstring)."""
    if isinstance(space, spaces.Dict):
        return {key: stack_observations([o[key] for o in observations], sub) for key, sub in space.spaces.items()}
    if isinstance(space, spaces.Tuple):
        return tuple(stack_observations([o[i] for o in observations], sub) for i, sub in enumerate(space.spaces))
    if isinstance(space, (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary)):
        # reshape, not stack: an empty batch keeps its shape too.
        return np.asarray(observations, dtype=space.dtype).reshape((len(observations), *space.shape))
    # Text, MiniGrid's MissionSpace, Graph, Sequence...: the observations as they are, one object per row. A
    # Python policy reads them; a network cannot, and says so when the load-time check calls it.
    batch = np.empty(len(observations), dtype=object)
    for i, observation in enumerate(observations):  # one by one: a row that is itself a sequence is never an axis
        batch[i] = observation
    return batch


def batch_size(obs: Any) -> int:
    """How many episodes a :func:`stack_observations` batch holds."""
    while isinstance(obs, (dict, tuple, list)):
        obs = next(iter(obs.values())) if isinstance(obs, dict) else obs[0]
    return len(obs)


def check_actions(agent: Agent, *, observation_space: gymnasium.Space, action_space: gymnasium.Space,
                  label: str) -> None:
    """Calls ``agent`` once on sampled observations; AgentError unless its actions lie in ``action_space``."""
    sampler = copy.deepcopy(observation_space)  # seeding the caller's space would change its own draws
    sampler.seed(0)
    try:
        batch = stack_observations([sampler.sample() for _ in range(CHECK_BATCH)], observation_space)
        actions, _ = agent.act(batch, agent.initial_state(CHECK_BATCH), np.random.default_rng(0))
    except AgentError as exc:
        raise AgentError(f"{label}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - user code and models fail in any way; say where.
        raise AgentError(f"{label}: acting on sample observations of {observation_space} failed "
                         f"({describe_exception(exc)})") from None
    actions = np.asarray(actions)
    if actions.shape != (CHECK_BATCH, *action_space.shape) or not all(action_space.contains(a) for a in actions):
        raise AgentError(f"{label}: actions {actions.tolist()} are not in the action space {action_space}")


def same_space(agent_space: Any, env_space: gymnasium.Space) -> bool:
    """Whether a policy's space fits the environment's: same type and shape (Discrete: same ``n``), recursively."""
    if type(agent_space) is not type(env_space):
        return False
    if isinstance(env_space, spaces.Discrete):
        return (agent_space.n, agent_space.start) == (env_space.n, env_space.start)
    if isinstance(env_space, spaces.MultiDiscrete):
        return np.array_equal(agent_space.nvec, env_space.nvec)
    if isinstance(env_space, (spaces.Box, spaces.MultiBinary)):
        return agent_space.shape == env_space.shape
    if isinstance(env_space, spaces.Dict):
        return (agent_space.spaces.keys() == env_space.spaces.keys()
                and all(same_space(agent_space[k], sub) for k, sub in env_space.spaces.items()))
    if isinstance(env_space, spaces.Tuple):
        return (len(agent_space.spaces) == len(env_space.spaces)
                and all(same_space(a, e) for a, e in zip(agent_space.spaces, env_space.spaces)))
    return agent_space == env_space


def check_space(agent_space: Any, env_space: gymnasium.Space, *, which: str, label: str,
                fits: Callable[[Any, gymnasium.Space], bool] = same_space) -> None:
    """AgentError naming both spaces unless ``fits(agent_space, env_space)``."""
    if not fits(agent_space, env_space):
        raise AgentError(f"{label}: {which} space {describe_space(agent_space)} does not match the environment's "
                         f"{describe_space(env_space)}")


def describe_space(space: Any) -> str:
    """A space in one short line: a Box by its shape and dtype (its bounds can fill a screen), others as printed."""
    if isinstance(space, spaces.Box):
        return f"Box(shape={space.shape}, {space.dtype})"
    if isinstance(space, spaces.Dict):
        return "Dict(" + ", ".join(f"{k}: {describe_space(v)}" for k, v in space.spaces.items()) + ")"
    if isinstance(space, spaces.Tuple):
        return "Tuple(" + ", ".join(describe_space(v) for v in space.spaces) + ")"
    return " ".join(str(space).split())


def require_discrete_or_box(action_space: gymnasium.Space, *, label: str) -> None:
    """AgentError unless ``action_space`` is Discrete or Box (what logits and Gaussian heads act in)."""
    if not isinstance(action_space, (spaces.Discrete, spaces.Box)):
        raise AgentError(f"{label}: action space {action_space} is not supported by this kind (Discrete or Box)")


def finish_actions(actions: Any, space: gymnasium.Space) -> np.ndarray:
    """Raw actions of ``n`` episodes as the array the environment takes: shaped, typed, Box clipped to bounds."""
    actions = np.asarray(actions)
    n = len(actions) if actions.ndim else 1
    if actions.size != n * int(np.prod(space.shape)):
        raise AgentError(f"it gives actions of shape {actions.shape[1:]}, the action space {space} has shape "
                         f"{space.shape}")
    actions = actions.reshape((n, *space.shape))
    if isinstance(space, spaces.Box):
        clipped = np.clip(actions.astype(np.float64), space.low, space.high)
        if np.issubdtype(space.dtype, np.floating):
            return clipped.astype(np.float32)
        return np.rint(clipped).astype(space.dtype)
    return actions.astype(np.int8 if isinstance(space, spaces.MultiBinary) else np.int64)


def categorical(logits: Any, space: spaces.Discrete, *, greedy: bool, rng: np.random.Generator) -> np.ndarray:
    """One action per row of ``logits`` ``(n, space.n)``: the argmax or a draw with ``rng``."""
    from dsage_ray.agents.sampling import sample_from_logits

    if logits.dim() != 2 or logits.shape[1] != space.n:
        raise AgentError(f"it gives logits of shape {tuple(logits.shape[1:])}, the action space {space} needs "
                         f"({space.n},)")
    index = logits.argmax(dim=-1).numpy() if greedy else sample_from_logits(logits, rng)
    return index.astype(np.int64) + int(space.start)


def gaussian(mean: np.ndarray, std: np.ndarray, *, greedy: bool, rng: np.random.Generator) -> np.ndarray:
    """The mean (greedy) or one draw of ``N(mean, std)`` per entry with ``rng``."""
    return mean if greedy else mean + std * rng.standard_normal(mean.shape)


def unsquash(actions: np.ndarray, space: spaces.Box) -> np.ndarray:
    """Maps ``[-1, 1]`` to a bounded Box's ``[low, high]`` (RLlib's and SB3's convention); unbounded: unchanged."""
    if not space.is_bounded():
        return actions
    return space.low + (actions + 1.0) * (space.high - space.low) / 2.0


def to_torch(obs: Any, *, time_axis: bool = False) -> Any:
    """A :func:`stack_observations` batch as tensors; float arrays as float32 (the weights' dtype)."""
    import torch

    def leaf(x: np.ndarray) -> Any:
        if np.issubdtype(x.dtype, np.floating):
            x = x.astype(np.float32, copy=False)
        tensor = torch.from_numpy(np.ascontiguousarray(x))
        return tensor[:, None] if time_axis else tensor

    return tree_map(leaf, obs)
