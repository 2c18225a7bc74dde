"""Agents of the gym domain: any policy for any Gymnasium environment, as a batched :class:`Agent`.

Spec forms (:data:`GYM_AGENT_FORMS`)::

    random                                    uniform random actions
    rllib:PATH | rllib:NAME                   a new-API-stack TorchRLModule (algorithm or RLModule checkpoint)
    sb3:PATH.zip                              a Stable-Baselines3 save (needs the ``sb3`` extra)
    torchscript:PATH                          forward(obs) -> logits (Discrete) or actions (Box)
    python:MODULE:FUNCTION | python:FILE.py:FUNCTION   a plain function from one observation to one action

Options: ``rllib:...?policy=NAME&greedy=0|1&normalize_actions=0|1`` and ``sb3:...?algo=PPO&greedy=0|1``;
``greedy=1`` takes the most likely action (argmax, Gaussian mean) instead of sampling (the default, as the
Maze agents do). ``normalize_actions`` (default 1, RLlib's own default) maps a Box policy's outputs from
``[-1, 1]`` to the action bounds, as RLlib's env runner does for a module trained with that setting.

Batches (:func:`stack_observations`): a Box observation arrives as ``(n, *shape)`` in the space's dtype, a
Discrete one as int64 ``(n,)``, a Dict as a dict and a Tuple as a tuple of such arrays, any other space (Text,
MiniGrid's mission) as an object array of the ``n`` observations. Actions leave as a numpy
array with ``n`` rows: int64 ``(n,)`` for Discrete, float32 ``(n, *shape)`` clipped to the bounds for a float
Box, int64 for MultiDiscrete, int8 for MultiBinary. Every draw comes from the caller's ``rng`` (never torch's),
so an evaluation is reproducible from its seed.

Before anything runs, the agent's own spaces (RLlib and SB3 record theirs) must match the environment's, and
every agent is called once on two sampled observations whose actions must lie in the action space; any problem
is an :class:`AgentError` of one line naming the spec or file.

Only RLlib modules may be recurrent (RLlib's inference layout: a time axis of 1, ``STATE_IN``/``STATE_OUT``);
the agent state is then a dict of ``(n, ...)`` tensors, else None. torch, ray and stable_baselines3 are
imported only by the kinds that need them.
"""

from __future__ import annotations

import copy
import hashlib
import importlib
import importlib.util
import inspect
import json
import zipfile
from pathlib import Path
from typing import Any, Callable

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState, _tree_map
from dsage_ray.agents.loader import KINDS_RUNNING_CODE, SpecOptions, describe_exception, parse_spec, require_file

#: The kinds and their spec forms (for the domain registration and error messages).
GYM_AGENT_FORMS: dict[str, str] = {
    "random": "random",
    "rllib": "rllib:PATH | rllib:NAME",
    "sb3": "sb3:PATH.zip",
    "torchscript": "torchscript:PATH",
    "python": "python:MODULE:FUNCTION | python:FILE.py:FUNCTION",
}
#: Whether loading a kind runs code the file or module brings (pickles, TorchScript, Python).
LOADING_RUNS_CODE: dict[str, bool] = {kind: kind in KINDS_RUNNING_CODE for kind in GYM_AGENT_FORMS}

#: Action spaces some kind can act in; rllib and torchscript act in the first two only.
_ACTION_SPACES = (spaces.Discrete, spaces.Box, spaces.MultiDiscrete, spaces.MultiBinary)
_SB3_SHIPPED_ALGOS = ("PPO", "A2C", "DQN", "SAC", "TD3", "DDPG")
#: SB3 saves the policy class, not the algorithm: its module names the algorithm, except for the
#: actor-critic policy that PPO and A2C share (told apart by PPO's ``clip_range``, see :func:`_sb3_algo`).
_SB3_POLICY_MODULES = {"stable_baselines3.dqn.policies": "DQN", "stable_baselines3.sac.policies": "SAC",
                       "stable_baselines3.td3.policies": "TD3"}
#: How many sampled observations the load-time check feeds the agent.
_CHECK_BATCH = 2

Loader = Callable[[str, SpecOptions, gymnasium.Space, gymnasium.Space], "tuple[Agent, str]"]


# --- public API -----------------------------------------------------------------------------------------------


def load_gym_agent(spec: str, *, observation_space: gymnasium.Space, action_space: gymnasium.Space) -> Agent:
    """Loads the agent a spec names and checks it against the environment's spaces.

    Args:
        spec: One of :data:`GYM_AGENT_FORMS`, with the kind's ``?options``.
        observation_space: The environment's (single-episode) observation space.
        action_space: The environment's (single-episode) action space.

    Returns:
        The agent, with ``agent.spec`` set to ``spec``; it acts on :func:`stack_observations` batches.

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
        agent, label = loader(target, options, observation_space, action_space)
        options.check_all_used()
    agent.spec = spec
    check_actions(agent, observation_space=observation_space, action_space=action_space, label=label)
    return agent


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


def check_actions(agent: Agent, *, observation_space: gymnasium.Space, action_space: gymnasium.Space,
                  label: str) -> None:
    """Calls ``agent`` once on sampled observations; AgentError unless its actions lie in ``action_space``."""
    sampler = copy.deepcopy(observation_space)  # seeding the caller's space would change its own draws
    sampler.seed(0)
    try:
        batch = stack_observations([sampler.sample() for _ in range(_CHECK_BATCH)], observation_space)
        actions, _ = agent.act(batch, agent.initial_state(_CHECK_BATCH), np.random.default_rng(0))
    except AgentError as exc:
        raise AgentError(f"{label}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - user code and models fail in any way; say where.
        raise AgentError(f"{label}: acting on sample observations of {observation_space} failed "
                         f"({describe_exception(exc)})") from None
    actions = np.asarray(actions)
    if actions.shape != (_CHECK_BATCH, *action_space.shape) or not all(action_space.contains(a) for a in actions):
        raise AgentError(f"{label}: actions {actions.tolist()} are not in the action space {action_space}")


# --- shared by the kinds --------------------------------------------------------------------------------------


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


def _check_space(agent_space: Any, env_space: gymnasium.Space, *, which: str, label: str,
                 fits: Callable[[Any, gymnasium.Space], bool] = same_space) -> None:
    if not fits(agent_space, env_space):
        raise AgentError(f"{label}: {which} space {agent_space} does not match the environment's {env_space}")


def _require_discrete_or_box(action_space: gymnasium.Space, *, label: str) -> None:
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


def _categorical(logits: Any, space: spaces.Discrete, *, greedy: bool, rng: np.random.Generator) -> np.ndarray:
    """One action per row of ``logits`` ``(n, space.n)``: the argmax or a draw with ``rng``."""
    from dsage_ray.agents.sampling import sample_from_logits

    if logits.dim() != 2 or logits.shape[1] != space.n:
        raise AgentError(f"it gives logits of shape {tuple(logits.shape[1:])}, the action space {space} needs "
                         f"({space.n},)")
    index = logits.argmax(dim=-1).numpy() if greedy else sample_from_logits(logits, rng)
    return index.astype(np.int64) + int(space.start)


def _gaussian(mean: np.ndarray, std: np.ndarray, *, greedy: bool, rng: np.random.Generator) -> np.ndarray:
    return mean if greedy else mean + std * rng.standard_normal(mean.shape)


def _unsquash(actions: np.ndarray, space: spaces.Box) -> np.ndarray:
    """Maps ``[-1, 1]`` to a bounded Box's ``[low, high]`` (RLlib's and SB3's convention); unbounded: unchanged."""
    if not space.is_bounded():
        return actions
    return space.low + (actions + 1.0) * (space.high - space.low) / 2.0


def _to_torch(obs: Any, *, time_axis: bool = False) -> Any:
    """A :func:`stack_observations` batch as tensors; float arrays as float32 (the weights' dtype)."""
    import torch

    def leaf(x: np.ndarray) -> Any:
        if np.issubdtype(x.dtype, np.floating):
            x = x.astype(np.float32, copy=False)
        tensor = torch.from_numpy(np.ascontiguousarray(x))
        return tensor[:, None] if time_axis else tensor

    return _tree_map(leaf, obs)


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
        n = len(_first_leaf(obs))
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


def _first_leaf(obs: Any) -> np.ndarray:
    while isinstance(obs, (dict, tuple, list)):
        obs = next(iter(obs.values())) if isinstance(obs, dict) else obs[0]
    return obs


# --- rllib ----------------------------------------------------------------------------------------------------


class RLlibGymAgent(Agent):
    """An RLModule acting in any Discrete or Box action space; state as :class:`~dsage_ray.agents.rllib.RLlibAgent`.

    Args:
        module: A ``TorchRLModule`` whose spaces match the environment's.
        greedy: Argmax / Gaussian mean instead of sampling.
        normalize_actions: Map Box outputs from ``[-1, 1]`` to the bounds (RLlib's ``normalize_actions``).
    """

    def __init__(self, *, module: Any, greedy: bool = False, normalize_actions: bool = True) -> None:
        from dsage_ray.agents.rllib import RLlibAgent

        # The Maze agent already handles eval mode and recurrent state; only the batch layout differs here.
        self._inner = RLlibAgent(module=module, greedy=greedy)
        self.module = self._inner.module
        self.greedy = greedy
        self.normalize_actions = normalize_actions
        self._squashed = _is_squashed_gaussian(module)

    def initial_state(self, batch_size: int) -> AgentState:
        return self._inner.initial_state(batch_size)

    def dist_inputs(self, obs: Any, state: AgentState) -> tuple[Any, AgentState]:
        """One module step: ``ACTION_DIST_INPUTS`` ``(n, k)`` and the next state; no sampling."""
        import torch
        from ray.rllib.core.columns import Columns

        batch = {Columns.OBS: _to_torch(obs, time_axis=self._inner.recurrent)}
        if self._inner.recurrent:
            batch[Columns.STATE_IN] = state
        with torch.inference_mode():
            out = self.module.forward_inference(batch) if self.greedy else self.module.forward_exploration(batch)
        inputs = out[Columns.ACTION_DIST_INPUTS]
        if self._inner.recurrent:
            return inputs[:, 0], out[Columns.STATE_OUT]
        return inputs, None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        inputs, state = self.dist_inputs(obs, state)
        space = self.module.action_space
        if isinstance(space, spaces.Discrete):
            return _categorical(inputs, space, greedy=self.greedy, rng=rng), state
        # RLlib's diagonal Gaussian layout: concat(mean, log_std) on the last axis.
        mean, log_std = np.split(inputs.double().numpy(), 2, axis=-1)
        actions = _gaussian(mean, np.exp(log_std), greedy=self.greedy, rng=rng)
        if self._squashed:
            actions = np.tanh(actions)
        if self.normalize_actions:
            actions = _unsquash(actions, space)
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
                action_space: gymnasium.Space) -> tuple[Agent, str]:
    from dsage_ray.agents.rllib import load_rllib_module

    policy = options.get_str("policy", "default_policy")
    greedy = options.get_bool("greedy", False)
    normalize = options.get_bool("normalize_actions", True)
    labels = []

    def check_env_spaces(module: Any, *, source: str) -> None:
        """The env's spaces in place of :func:`~dsage_ray.agents.rllib.check_spaces`'s Maze ones."""
        label = f"rllib checkpoint {source!r}"
        _check_space(module.observation_space, observation_space, which="observation", label=label)
        _check_space(module.action_space, action_space, which="action", label=label)
        _require_discrete_or_box(action_space, label=label)
        labels.append(label)

    module = load_rllib_module(target, policy=policy, check=check_env_spaces)
    return RLlibGymAgent(module=module, greedy=greedy, normalize_actions=normalize), labels[0]


# --- sb3 ------------------------------------------------------------------------------------------------------


class SB3Agent(Agent):
    """A Stable-Baselines3 model; stateless. Sampling reads the policy's distribution and draws with ``rng``.

    Args:
        model: The loaded algorithm (``PPO.load(...)`` etc.).
        greedy: The policy's deterministic action (``predict(deterministic=True)``) instead of sampling.
    """

    def __init__(self, *, model: Any, greedy: bool = False) -> None:
        self.model = model
        self.policy = model.policy.eval()
        self.greedy = greedy

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        import torch

        space = self.policy.action_space
        if not self.greedy:
            obs_tensor, _ = self.policy.obs_to_tensor(obs)
            with torch.no_grad():
                dist = _sb3_distribution(self.policy, obs_tensor)
                if dist is not None:
                    actions = _sb3_sample(dist, rng)
                    if isinstance(space, spaces.Box) and self.policy.squash_output:
                        actions = _unsquash(actions, space)
                    return finish_actions(actions, space), None
        # predict() does SB3's own preprocessing, unscaling and clipping: exactly the deterministic action.
        best, _ = self.policy.predict(obs, deterministic=True)
        return finish_actions(best if self.greedy else self._epsilon_greedy(best, rng), space), None

    def _epsilon_greedy(self, best: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """DQN's exploration (its ``predict(deterministic=False)``), per episode; TD3/DDPG have none (rate 0)."""
        rate = float(getattr(self.model, "exploration_rate", 0.0) or 0.0)
        space = self.policy.action_space
        if rate <= 0.0 or not isinstance(space, spaces.Discrete):
            return best
        explore = rng.random(len(best)) < rate
        return np.where(explore, space.start + rng.integers(0, space.n, size=len(best)), best)


def _sb3_distribution(policy: Any, obs_tensor: Any) -> Any:
    """The policy's action distribution (actor-critic or SAC-style actor), or None for value/deterministic ones."""
    if hasattr(policy, "get_distribution"):
        return policy.get_distribution(obs_tensor)
    actor = getattr(policy, "actor", None)
    if actor is not None and hasattr(actor, "get_action_dist_params"):
        mean, log_std, kwargs = actor.get_action_dist_params(obs_tensor)
        return actor.action_dist.proba_distribution(mean, log_std, **kwargs)
    return None


def _sb3_sample(dist: Any, rng: np.random.Generator) -> np.ndarray:
    """One draw per row from an SB3 distribution, with ``rng``."""
    from stable_baselines3.common import distributions as sb3_dist

    from dsage_ray.agents.sampling import sample_from_logits

    if isinstance(dist, sb3_dist.CategoricalDistribution):
        return sample_from_logits(dist.distribution.logits, rng)
    if isinstance(dist, sb3_dist.MultiCategoricalDistribution):
        return np.stack([sample_from_logits(part.logits, rng) for part in dist.distribution], axis=1)
    if isinstance(dist, sb3_dist.BernoulliDistribution):
        probs = dist.distribution.probs.double().numpy()
        return (rng.random(probs.shape) < probs).astype(np.int8)
    if isinstance(dist, sb3_dist.DiagGaussianDistribution):  # SquashedDiagGaussian (SAC) included
        normal = dist.distribution
        actions = _gaussian(normal.mean.double().numpy(), normal.stddev.double().numpy(), greedy=False, rng=rng)
        return np.tanh(actions) if isinstance(dist, sb3_dist.SquashedDiagGaussianDistribution) else actions
    raise AgentError(f"sampling from SB3's {type(dist).__name__} is not supported (gSDE?); use ?greedy=1")


def _sb3_algo(path: Path, *, label: str) -> str:
    """The algorithm that saved ``path``, read from the zip's ``data`` JSON without unpickling anything."""
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except zipfile.BadZipFile:
        raise AgentError(f"{label}: not a zip file (expected a Stable-Baselines3 .zip save)") from None
    except KeyError:
        raise AgentError(f"{label}: no 'data' entry in the zip (not a Stable-Baselines3 save)") from None
    except (OSError, ValueError) as exc:
        raise AgentError(f"{label}: unreadable Stable-Baselines3 save ({describe_exception(exc)})") from None
    policy = data.get("policy_class") if isinstance(data, dict) else None
    module = policy.get("__module__") if isinstance(policy, dict) else None
    if module == "stable_baselines3.common.policies":
        return "PPO" if "clip_range" in data else "A2C"
    if module in _SB3_POLICY_MODULES:
        return _SB3_POLICY_MODULES[module]
    raise AgentError(f"{label}: cannot tell the algorithm from its policy class ({module or 'not recorded'}); "
                     f"name it with ?algo= ({', '.join(_SB3_SHIPPED_ALGOS)})")


def _sb3_observation_fits(agent_space: Any, env_space: gymnasium.Space) -> bool:
    """Like :func:`same_space`, but SB3 models of channel-last images record (and transpose to) channel-first."""
    if same_space(agent_space, env_space):
        return True
    return (isinstance(agent_space, spaces.Box) and isinstance(env_space, spaces.Box) and len(env_space.shape) == 3
            and agent_space.shape == (env_space.shape[2], *env_space.shape[:2]))


def _load_sb3(target: str, options: SpecOptions, observation_space: gymnasium.Space,
              action_space: gymnasium.Space) -> tuple[Agent, str]:
    try:
        import stable_baselines3
    except ImportError:
        raise AgentError("sb3: agents need the sb3 extra: pip install 'dsage_ray[sb3]'") from None
    algo = options.get_str("algo", "").upper()
    greedy = options.get_bool("greedy", False)
    path = require_file(target, what="sb3 file")
    label = f"sb3 file {str(path)!r}"
    if algo and algo not in _SB3_SHIPPED_ALGOS:
        raise AgentError(f"{label}: unknown ?algo={algo} (known: {', '.join(_SB3_SHIPPED_ALGOS)})")
    algo = algo or _sb3_algo(path, label=label)
    try:
        model = getattr(stable_baselines3, algo).load(str(path), device="cpu")
    except Exception as exc:  # noqa: BLE001 - a corrupt or foreign zip fails in any way
        raise AgentError(f"{label}: cannot load it as {algo} ({describe_exception(exc)})") from None
    _check_space(model.observation_space, observation_space, which="observation", label=label,
                 fits=_sb3_observation_fits)
    _check_space(model.action_space, action_space, which="action", label=label)
    return SB3Agent(model=model, greedy=greedy), label


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
            out = self.module(_to_torch(obs))
        if not isinstance(out, torch.Tensor):
            raise AgentError(f"forward(obs) returned {type(out).__name__}, not a tensor")
        if isinstance(self.action_space, spaces.Discrete):
            return _categorical(out, self.action_space, greedy=False, rng=rng), None
        return finish_actions(out.double().numpy(), self.action_space), None


def _load_torchscript(target: str, options: SpecOptions, observation_space: gymnasium.Space,
                      action_space: gymnasium.Space) -> tuple[Agent, str]:
    from dsage_ray.agents.torchscript import load_script_module

    path = require_file(target, what="torchscript file")
    label = f"torchscript file {str(path)!r}"
    _require_discrete_or_box(action_space, label=label)
    return TorchScriptGymAgent(module=load_script_module(path), action_space=action_space), label


# --- python ---------------------------------------------------------------------------------------------------


class PythonFunctionAgent(Agent):
    """A plain function from one observation to one action, called per episode.

    A function with an ``rng`` parameter gets the caller's generator (so a stochastic policy stays
    reproducible); any other function must be deterministic.

    Args:
        function: ``function(observation[, rng=rng]) -> action``.
        action_space: The environment's action space.
    """

    def __init__(self, *, function: Callable[..., Any], action_space: gymnasium.Space) -> None:
        self.function = function
        self.action_space = action_space
        self._takes_rng = _accepts_rng(function)

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        extra = {"rng": rng} if self._takes_rng else {}
        n = len(_first_leaf(obs))
        actions = [self.function(_tree_map(lambda x, i=i: x[i], obs), **extra) for i in range(n)]
        return finish_actions(np.asarray(actions), self.action_space), None


def _accepts_rng(function: Callable[..., Any]) -> bool:
    try:
        return "rng" in inspect.signature(function).parameters
    except (TypeError, ValueError):  # builtins without a signature
        return False


def _load_python(target: str, options: SpecOptions, observation_space: gymnasium.Space,
                 action_space: gymnasium.Space) -> tuple[Agent, str]:
    location, sep, name = target.rpartition(":")
    if not sep or not location or not name:
        raise AgentError(f"python policy {target!r}: expected python:MODULE:FUNCTION or python:FILE.py:FUNCTION")
    label = f"python policy {target!r}"
    module = _import_file(location, label=label) if location.endswith(".py") else _import_module(location, label=label)
    function = getattr(module, name, None)
    if function is None:
        raise AgentError(f"{label}: {location!r} has no function {name!r}")
    if not callable(function):
        raise AgentError(f"{label}: {location}.{name} is a {type(function).__name__}, not callable")
    return PythonFunctionAgent(function=function, action_space=action_space), label


def _import_module(name: str, *, label: str) -> Any:
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name and (name == exc.name or name.startswith(exc.name + ".")):
            raise AgentError(f"{label}: module {name!r} not found (is it installed or on PYTHONPATH?)") from None
        raise AgentError(f"{label}: importing {name!r} failed ({describe_exception(exc)})") from None
    except Exception as exc:  # noqa: BLE001 - the module's own top-level code can raise anything
        raise AgentError(f"{label}: importing {name!r} failed ({describe_exception(exc)})") from None


def _import_file(location: str, *, label: str) -> Any:
    """Imports a .py file from where it lies, without adding its folder to ``sys.path``."""
    import sys

    path = require_file(location, what="python policy file").resolve()
    # A name of its own per file: two policies called pol.py must not replace each other in sys.modules.
    name = f"_dsage_gym_policy_{path.stem}_{hashlib.sha256(str(path).encode()).hexdigest()[:12]}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise AgentError(f"{label}: {str(path)!r} cannot be imported as a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look the module up while it runs
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - the file's top-level code can raise anything
        sys.modules.pop(name, None)
        raise AgentError(f"{label}: importing {str(path)!r} failed ({describe_exception(exc)})") from None
    return module


_LOADERS: dict[str, Loader] = {"rllib": _load_rllib, "sb3": _load_sb3, "torchscript": _load_torchscript,
                               "python": _load_python}
