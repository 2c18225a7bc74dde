"""Agents of the gym domain: any policy for any Gymnasium environment, as a batched :class:`Agent`.

Spec forms (:data:`GYM_AGENT_FORMS`)::

    random                                    uniform random actions
    rllib:PATH | rllib:NAME                   a new-API-stack TorchRLModule (algorithm or RLModule checkpoint)
    sb3:PATH.zip | sb3:RUN_FOLDER             a Stable-Baselines3 save, or an RL Zoo run folder played as trained
    torchscript:PATH                          forward(obs) -> logits (Discrete) or actions (Box)
    python:MODULE:FUNCTION | python:FILE.py:FUNCTION   a plain function (``?batch=1``: over the batch)

Options: ``rllib:...?policy=NAME&greedy=0|1&normalize_actions=0|1``, ``sb3:...?algo=PPO&greedy=0|1``
(:mod:`dsage_ray.agents.sb3`) and ``python:...?batch=1`` (:mod:`dsage_ray.agents.python_policy`); ``greedy=1``
takes the most likely action (argmax, Gaussian mean) instead of sampling (the default, as the Maze agents do).
``normalize_actions`` (default 1, RLlib's own default) maps a Box policy's outputs from ``[-1, 1]`` to the action
bounds, as RLlib's env runner does for a module trained with that setting.

Observations go in and actions come out as :mod:`dsage_ray.agents.spaces` batches them. Before anything runs, the
agent's own spaces (RLlib and SB3 record theirs) must match the environment's (as the agent's training-time wrappers
leave it: :meth:`Agent.wrap_env`), and every agent is called once on two sampled observations whose actions must lie
in the action space; any problem is an :class:`AgentError` of one line naming the spec or file.

Only RLlib modules may be recurrent (RLlib's inference layout: a time axis of 1, ``STATE_IN``/``STATE_OUT``);
the agent state is then a dict of ``(n, ...)`` tensors, else None. torch, ray and stable_baselines3 are
imported only by the kinds that need them.
"""

from __future__ import annotations

from typing import Any, Callable

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState
from dsage_ray.agents.loader import KINDS_RUNNING_CODE, SpecOptions, parse_spec, require_file
from dsage_ray.agents.spaces import (batch_size, categorical, check_actions, check_space, finish_actions, gaussian,
                                     require_discrete_or_box, stack_observations, to_torch, unsquash)

__all__ = ["GYM_AGENT_FORMS", "LOADING_RUNS_CODE", "RandomGymAgent", "RLlibGymAgent", "TorchScriptGymAgent",
           "load_gym_agent", "stack_observations"]

#: The kinds and their spec forms (for the domain registration and error messages).
GYM_AGENT_FORMS: dict[str, str] = {
    "random": "random",
    "rllib": "rllib:PATH | rllib:NAME",
    "sb3": "sb3:PATH.zip | sb3:RUN_FOLDER",
    "torchscript": "torchscript:PATH",
    "python": "python:MODULE:FUNCTION | python:FILE.py:FUNCTION",
}
#: Whether loading a kind runs code the file or module brings (pickles, TorchScript, Python).
LOADING_RUNS_CODE: dict[str, bool] = {kind: kind in KINDS_RUNNING_CODE for kind in GYM_AGENT_FORMS}

#: Action spaces some kind can act in; rllib and torchscript act in the first two only.
_ACTION_SPACES = (spaces.Discrete, spaces.Box, spaces.MultiDiscrete, spaces.MultiBinary)

Loader = Callable[[str, SpecOptions, gymnasium.Space, gymnasium.Space, Any], "tuple[Agent, str]"]


# --- public API -----------------------------------------------------------------------------------------------


def load_gym_agent(spec: str, *, observation_space: gymnasium.Space, action_space: gymnasium.Space,
                   env: Any = None) -> Agent:
    """Loads the agent a spec names and checks it against the environment's spaces.

    Args:
        spec: One of :data:`GYM_AGENT_FORMS`, with the kind's ``?options``.
        observation_space: The environment's (single-episode) observation space.
        action_space: The environment's (single-episode) action space.
        env: The environment itself, for agents played inside training-time wrappers (an RL Zoo folder's
            ``env_wrapper``); without it such an agent is refused.

    Returns:
        The agent, with ``agent.spec`` set to ``spec``; it acts on
        :func:`~dsage_ray.agents.spaces.stack_observations` batches of the environment as
        :meth:`Agent.wrap_env` wraps it.

    Raises:
        AgentError: Unknown kind or option, a target that cannot be loaded, spaces that do not match, or an
            agent whose actions on sampled observations are not in the action space; one line each.
    """
    if not isinstance(action_space, _ACTION_SPACES):
        raise AgentError(f"agent spec {spec!r}: action space {action_space} is not supported "
                         f"(Discrete, Box, MultiDiscrete or MultiBinary)")
    if spec.strip() == "random":
        agent, label = RandomGymAgent(action_space=action_space), f"agent spec {spec!r}"
    else:
        kind, target, options = parse_spec(spec)
        loader = _LOADERS.get(kind)
        if loader is None:
            raise AgentError(f"agent spec {spec!r}: unknown kind {kind!r} for gym environments (known: "
                             f"{'; '.join(GYM_AGENT_FORMS.values())})")
        agent, label = loader(target, options, observation_space, action_space, env)
        options.check_all_used()
    agent.spec = spec
    if env is not None:  # the policy sees the environment inside its wrappers
        observation_space = agent.wrap_env(env).observation_space
    check_actions(agent, observation_space=observation_space, action_space=action_space, label=label)
    return agent


# --- random ---------------------------------------------------------------------------------------------------


class RandomGymAgent(Agent):
    """Uniformly random actions (Box: uniform within finite bounds, standard normal where unbounded).

    Args:
        action_space: The environment's action space.
    """

    def __init__(self, *, action_space: gymnasium.Space) -> None:
        self.action_space = action_space

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        n = batch_size(obs)
        space = self.action_space
        size = (n, *space.shape)
        if isinstance(space, spaces.Discrete):
            actions = space.start + rng.integers(0, space.n, size=n)
        elif isinstance(space, spaces.MultiDiscrete):
            actions = space.start + rng.integers(0, space.nvec, size=size)
        elif isinstance(space, spaces.MultiBinary):
            actions = rng.integers(0, 2, size=size)
        else:
            bounded = np.isfinite(space.low) & np.isfinite(space.high)
            width = np.where(bounded, space.high - space.low, 0.0)
            uniform = np.where(bounded, space.low, 0.0) + rng.random(size) * width
            actions = np.where(bounded, uniform, rng.standard_normal(size))
        return finish_actions(actions, space), None


# --- rllib ----------------------------------------------------------------------------------------------------


class RLlibGymAgent(Agent):
    """An RLModule acting in any Discrete or Box action space; state as :class:`~dsage_ray.agents.rllib.RLlibAgent`.

    Args:
        module: A ``TorchRLModule`` whose spaces match the environment's (or its pipeline's, with ``pipelines``).
        greedy: Argmax / Gaussian mean instead of sampling.
        normalize_actions: Map Box outputs from ``[-1, 1]`` to the bounds (RLlib's ``normalize_actions``).
        pipelines: An algorithm checkpoint's restored connector pipelines
            (:mod:`dsage_ray.agents.rllib_connectors`), or None.
    """

    def __init__(self, *, module: Any, greedy: bool = False, normalize_actions: bool = True,
                 pipelines: Any = None) -> None:
        from dsage_ray.agents.rllib import RLlibAgent

        # The Maze agent already handles eval mode, recurrent state and the pipelines; only the batch layout of
        # the direct path differs here.
        self._inner = RLlibAgent(module=module, greedy=greedy, pipelines=pipelines)
        self.module = self._inner.module
        #: The pipelines it plays behind (None: none, or only RLlib's default pieces).
        self.pipelines = self._inner.pipelines
        self.greedy = greedy
        self.normalize_actions = normalize_actions
        self._squashed = _is_squashed_gaussian(module)

    def initial_state(self, batch_size: int) -> AgentState:
        return self._inner.initial_state(batch_size)

    def select_state(self, state: AgentState, index: np.ndarray) -> AgentState:
        return self._inner.select_state(state, index)

    def dist_inputs(self, obs: Any, state: AgentState) -> tuple[Any, AgentState]:
        """One module step: ``ACTION_DIST_INPUTS`` ``(n, k)`` and the next state; no sampling."""
        from ray.rllib.core.columns import Columns

        if self.pipelines is not None:
            return self._inner.piped_step(obs, state)
        batch = {Columns.OBS: to_torch(obs, time_axis=self._inner.recurrent)}
        if self._inner.recurrent:
            batch[Columns.STATE_IN] = state
        out = self._inner.forward(batch)
        inputs = out[Columns.ACTION_DIST_INPUTS]
        if self._inner.recurrent:
            return inputs[:, 0], out[Columns.STATE_OUT]
        return inputs, None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        from dsage_ray.agents.rllib_connectors import EpisodeState

        inputs, state = self.dist_inputs(obs, state)
        piped = isinstance(state, EpisodeState)
        space = self.module.action_space
        if isinstance(space, spaces.Discrete):
            actions = categorical(inputs, space, greedy=self.greedy, rng=rng)
            return actions, (state.acted(actions) if piped else state)
        # RLlib's diagonal Gaussian layout: concat(mean, log_std) on the last axis.
        mean, log_std = np.split(inputs.double().numpy(), 2, axis=-1)
        actions = gaussian(mean, np.exp(log_std), greedy=self.greedy, rng=rng)
        if self._squashed:
            actions = np.tanh(actions)
        # Episodes keep the module's own action (before normalisation), as RLlib's env runner keeps it.
        state = state.acted(actions.astype(np.float32)) if piped else state
        if self.normalize_actions:
            actions = unsquash(actions, space)
        return finish_actions(actions, space), state


def _is_squashed_gaussian(module: Any) -> bool:
    """Whether the module's actions pass through tanh (RLlib's SAC), read from its inference distribution."""
    from ray.rllib.core.distribution.torch.torch_distribution import TorchSquashedGaussian

    try:
        dist = module.get_inference_action_dist_cls()
    except Exception:  # noqa: BLE001 - a custom module may define none: then its inputs are a plain Gaussian.
        return False
    return isinstance(dist, type) and issubclass(dist, TorchSquashedGaussian)


def _load_rllib(target: str, options: SpecOptions, observation_space: gymnasium.Space,
                action_space: gymnasium.Space, env: Any = None) -> tuple[Agent, str]:
    from dsage_ray.agents.rllib import load_rllib_policy

    policy = options.get_str("policy", "default_policy")
    greedy = options.get_bool("greedy", False)
    labels = []

    def check_env_spaces(module: Any, *, source: str, observation_space: Any) -> None:
        """The env's spaces in place of :func:`~dsage_ray.agents.rllib.check_spaces`'s Maze ones."""
        label = f"rllib checkpoint {source!r}"
        check_space(observation_space, env_observation_space, which="observation", label=label)
        check_space(module.action_space, action_space, which="action", label=label)
        require_discrete_or_box(action_space, label=label)
        labels.append(label)

    env_observation_space = observation_space
    module, pipelines = load_rllib_policy(target, policy=policy, check=check_env_spaces)
    # The checkpoint's NormalizeAndClipActions says how it was trained; the option overrides it.
    recorded = pipelines.normalize_actions if pipelines is not None else None
    normalize = options.get_bool("normalize_actions", True if recorded is None else recorded)
    return RLlibGymAgent(module=module, greedy=greedy, normalize_actions=normalize, pipelines=pipelines), labels[0]


# --- torchscript ----------------------------------------------------------------------------------------------


class TorchScriptGymAgent(Agent):
    """A scripted ``forward(obs)``: logits ``(n, k)`` for Discrete(k) (sampled), actions ``(n, *shape)`` for Box.

    ``obs`` is the :func:`stack_observations` batch as tensors (floats as float32; a Dict as a dict).

    Args:
        module: The scripted module.
        action_space: The environment's Discrete or Box action space.
    """

    def __init__(self, *, module: Any, action_space: gymnasium.Space) -> None:
        self.module = module.eval()
        self.action_space = action_space

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        import torch

        with torch.inference_mode():
            out = self.module(to_torch(obs))
        if not isinstance(out, torch.Tensor):
            raise AgentError(f"forward(obs) returned {type(out).__name__}, not a tensor")
        if isinstance(self.action_space, spaces.Discrete):
            return categorical(out, self.action_space, greedy=False, rng=rng), None
        return finish_actions(out.double().numpy(), self.action_space), None


def _load_torchscript(target: str, options: SpecOptions, observation_space: gymnasium.Space,
                      action_space: gymnasium.Space, env: Any = None) -> tuple[Agent, str]:
    from dsage_ray.agents.torchscript import load_script_module

    path = require_file(target, what="torchscript file")
    label = f"torchscript file {str(path)!r}"
    require_discrete_or_box(action_space, label=label)
    return TorchScriptGymAgent(module=load_script_module(path), action_space=action_space), label


# --- sb3 and python (the agent layer's loaders) ---------------------------------------------------------------


def _load_sb3(target: str, options: SpecOptions, observation_space: gymnasium.Space,
              action_space: gymnasium.Space, env: Any = None) -> tuple[Agent, str]:
    from dsage_ray.agents.sb3 import load_sb3_agent

    return load_sb3_agent(target, options, observation_space=observation_space, action_space=action_space, env=env)


def _load_python(target: str, options: SpecOptions, observation_space: gymnasium.Space,
                 action_space: gymnasium.Space, env: Any = None) -> tuple[Agent, str]:
    from dsage_ray.agents.python_policy import load_python_agent

    return load_python_agent(target, options, action_space=action_space)


_LOADERS: dict[str, Loader] = {"rllib": _load_rllib, "sb3": _load_sb3, "torchscript": _load_torchscript,
                               "python": _load_python}
