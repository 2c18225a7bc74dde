"""RLlib policies (``rllib:PATH``): an RLModule from a new-API-stack checkpoint, run batched in our simulator.

``PATH`` may be

* an RLlib **algorithm checkpoint** folder (what ``algo.save_to_path`` writes); the module is read from
  ``learner_group/learner/rl_module/<policy>``;
* an **RLModule** checkpoint folder (that sub-folder, or what ``module.save_to_path`` writes);
* the name of an agent shipped with the package under ``dsage_ray/assets/agents/`` (``rllib:ppo_maze``),
  used when no folder of that name exists.

The module is loaded with ``RLModule.from_checkpoint``: no Ray cluster starts and no env runner is built. An
algorithm checkpoint's env-to-module and module-to-env connector pipelines (``env_runner/...``) are restored too,
with RLlib's own classes, and observations go through them as in RLlib's inference
(:mod:`dsage_ray.agents.rllib_connectors`: ``MeanStdFilter`` frozen with its statistics, frame stacking,
flattening; connectors an agent cannot feed are refused). A bare RLModule folder has no pipelines: the module sees
the observations as they are.
The module's class is stored in the checkpoint by import path, so it must be importable here; the project's
own :class:`~dsage_ray.agents.rllib_module.MazeRLModule` always is. Any ``TorchRLModule`` works whose observation
space (or its pipeline's input space) and action space match the environment's (:func:`load_rllib`); the Maze
registers its own check, MiniGrid's observation and ``Discrete(k)``, ``k <= 7``
(:mod:`dsage_ray.domains.maze.agents.rllib`).

Recurrent modules (a non-empty ``get_initial_state()``) get RLlib's inference layout: a time axis of
length 1 on every input, ``STATE_IN`` in, ``STATE_OUT`` out. Discrete actions are sampled from
``softmax(ACTION_DIST_INPUTS)``, Box ones from RLlib's diagonal Gaussian ``concat(mean, log_std)`` (tanh-squashed
for SAC), with the caller's numpy ``rng`` (never torch's), so evaluations are reproducible from their seed.

Options (``rllib:PATH?policy=default_policy&greedy=0&normalize_actions=1``):
    policy: Module id inside an algorithm checkpoint (default ``default_policy``).
    greedy: 1 takes the most likely action (argmax, Gaussian mean) instead of sampling (default 0).
    normalize_actions: 1 maps a Box policy's outputs from ``[-1, 1]`` to the action bounds, as RLlib's env runner
        does for a module trained with that setting (default: what the checkpoint's pipeline records, else 1).
"""

from __future__ import annotations

import io
import pickle
from pathlib import Path
from typing import Any, Callable

import gymnasium
import numpy as np
import torch
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState
from dsage_ray.agents.loader import (SpecOptions, describe_exception, local_path, shipped_agent_dir,
                                     shipped_agent_names)
from dsage_ray.agents.rllib_connectors import ConnectorPipelines, EpisodeState, load_pipelines, pipelines_dir
from dsage_ray.agents.spaces import (categorical, check_space, finish_actions, gaussian, require_discrete_or_box,
                                     to_torch, unsquash)

#: Where an algorithm checkpoint keeps its modules (``<ckpt>/<this>/<module id>``).
MODULES_SUBDIR = Path("learner_group") / "learner" / "rl_module"
CTOR_FILE = "class_and_ctor_args.pkl"


class RLlibAgent(Agent):
    """A loaded RLModule as a batched agent acting in a Discrete or Box action space.

    State: ``None`` or the module's state dict of ``(n, ...)`` tensors; behind connector pipelines, an
    :class:`~dsage_ray.agents.rllib_connectors.EpisodeState` (one RLlib episode per running episode, which also
    holds a recurrent module's state, as in RLlib's env runner).

    Args:
        module: A ``TorchRLModule`` whose spaces the loader checked against the environment's.
        greedy: Argmax / Gaussian mean instead of sampling.
        normalize_actions: Map Box outputs from ``[-1, 1]`` to the bounds (RLlib's ``normalize_actions``).
        pipelines: The checkpoint's restored connector pipelines, or None. Pipelines of RLlib's default pieces
            only (no ``transforms``) act as the direct path does, which is then kept.
    """

    def __init__(self, *, module: Any, greedy: bool = False, normalize_actions: bool = True,
                 pipelines: ConnectorPipelines | None = None) -> None:
        self.module = module.eval()
        self.greedy = greedy
        self.normalize_actions = normalize_actions
        #: The pipelines it plays behind (None: none, or only RLlib's default pieces).
        self.pipelines = pipelines if pipelines is not None and pipelines.transforms else None
        initial = module.get_initial_state() if hasattr(module, "get_initial_state") else {}
        #: One episode's initial state, as tensors; empty for a feed-forward module.
        self._initial = {k: torch.as_tensor(np.asarray(v)) for k, v in (initial or {}).items()}
        self._squashed = isinstance(module.action_space, spaces.Box) and _is_squashed_gaussian(module)

    @property
    def recurrent(self) -> bool:
        return bool(self._initial)

    def initial_state(self, batch_size: int) -> AgentState:
        if self.pipelines is not None:
            return self.pipelines.initial_state(batch_size)
        if not self.recurrent:
            return None
        return {k: v.unsqueeze(0).repeat(batch_size, *([1] * v.dim())) for k, v in self._initial.items()}

    def select_state(self, state: AgentState, index: np.ndarray) -> AgentState:
        if isinstance(state, EpisodeState):
            return state.select(index)
        return super().select_state(state, index)

    def forward(self, batch: dict[str, Any]) -> dict[str, Any]:
        """The module's greedy (``forward_inference``) or sampling (``forward_exploration``) pass, without grad."""
        with torch.inference_mode():
            return self.module.forward_inference(batch) if self.greedy else self.module.forward_exploration(batch)

    def piped_step(self, obs: Any, state: EpisodeState) -> tuple[torch.Tensor, EpisodeState]:
        """One step behind the connector pipelines: ``ACTION_DIST_INPUTS`` ``(n, ...)`` and the state after it.

        The caller records its actions with ``state.acted(actions)`` before the next step.
        """
        from ray.rllib.core.columns import Columns

        out = self.forward(self.pipelines.module_batch(self.module, obs, state, explore=not self.greedy))
        inputs = out[Columns.ACTION_DIST_INPUTS]
        # RLlib's RemoveSingleTsTimeRankFromBatch: a stateful module's outputs have a time axis of 1.
        return (inputs[:, 0] if self.recurrent else inputs), state.after(out)

    def logits(self, obs: Any, state: AgentState) -> tuple[torch.Tensor, AgentState]:
        """One module step: ``ACTION_DIST_INPUTS`` ``(n, k)`` (a Discrete module's logits) and the next state; no
        sampling."""
        from ray.rllib.core.columns import Columns

        if self.pipelines is not None:
            return self.piped_step(obs, state)
        # RLlib's env-to-module connector adds a time axis of 1 for stateful modules; so do we.
        batch = {Columns.OBS: to_torch(obs, time_axis=self.recurrent)}
        if self.recurrent:
            batch[Columns.STATE_IN] = state
        out = self.forward(batch)
        inputs = out[Columns.ACTION_DIST_INPUTS]
        if self.recurrent:
            return inputs[:, 0], out[Columns.STATE_OUT]
        return inputs, None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        inputs, state = self.logits(obs, state)
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


def resolve_module_dir(target: str, *, policy: str = "default_policy") -> Path:
    """The RLModule folder that ``target`` names (module docstring); AgentError when there is none."""
    return resolve_checkpoint(target, policy=policy)[0]


def resolve_checkpoint(target: str, *, policy: str = "default_policy") -> tuple[Path, Path | None]:
    """The RLModule folder that ``target`` names and the algorithm checkpoint it lies in (None for a bare module)."""
    path = shipped_agent_dir(target) or Path(local_path(target)).expanduser()
    if not path.exists():
        shipped = shipped_agent_names(holding=CTOR_FILE)
        raise AgentError(f"rllib checkpoint {str(path)!r}: not found"
                         + (f" (shipped agents: {', '.join(shipped)})" if shipped else ""))
    if not path.is_dir():
        raise AgentError(f"rllib checkpoint {str(path)!r}: not a folder (expected an RLlib algorithm "
                         f"or RLModule checkpoint folder)")
    # An algorithm (or learner) checkpoint has its own class file at the top: look for modules first.
    for modules in (path / MODULES_SUBDIR, path / "rl_module"):
        if modules.is_dir():
            if (modules / policy / CTOR_FILE).is_file():
                return modules / policy, (path if modules == path / MODULES_SUBDIR else None)
            found = sorted(p.name for p in modules.iterdir() if p.is_dir())
            raise AgentError(f"rllib checkpoint {str(path)!r}: no module {policy!r} (modules: "
                             f"{', '.join(found) or 'none'}); pick one with ?policy=NAME")
    if (path / CTOR_FILE).is_file():
        return path, None
    raise AgentError(f"rllib checkpoint {str(path)!r}: not an RLlib checkpoint (no {CTOR_FILE} and no "
                     f"{MODULES_SUBDIR.as_posix()}/ inside)")


class _RecordingUnpickler(pickle.Unpickler):
    """Unpickles, but names the class that cannot be imported instead of failing deep inside RLlib."""

    def find_class(self, module: str, name: str):
        try:
            return super().find_class(module, name)
        except (ImportError, AttributeError) as exc:
            raise AgentError(f"class {module}.{name} cannot be imported ({describe_exception(exc)})") from None


def module_class(module_dir: Path) -> type:
    """The RLModule class recorded in ``module_dir``; AgentError if it cannot be imported or read.

    RLlib's own ``from_checkpoint`` silently falls back to the abstract base class when the recorded
    class is missing, which then fails obscurely; reading the record ourselves gives a clear message.
    """
    source = str(module_dir)
    try:
        info = _RecordingUnpickler(io.BytesIO((module_dir / CTOR_FILE).read_bytes())).load()
    except AgentError as exc:
        raise AgentError(f"rllib checkpoint {source!r}: module {exc}; install or put on PYTHONPATH the package "
                         f"that defines it") from None
    except Exception as exc:  # noqa: BLE001 - a corrupt pickle raises anything
        raise AgentError(f"rllib checkpoint {source!r}: unreadable {CTOR_FILE} ({describe_exception(exc)})") from None
    cls = info.get("class") if isinstance(info, dict) else None
    from ray.rllib.core.rl_module.torch import TorchRLModule

    if not (isinstance(cls, type) and issubclass(cls, TorchRLModule)):
        raise AgentError(f"rllib checkpoint {source!r}: holds {cls!r}, not a TorchRLModule")
    return cls


def load_rllib_module(target: str, *, policy: str = "default_policy", check: Callable[..., None] | None = None):
    """Loads only the RLModule a checkpoint holds (no Ray cluster, no connector pipelines), with its spaces checked.

    Args:
        target: What ``rllib:PATH`` names (module docstring).
        policy: Module id inside an algorithm checkpoint.
        check: ``check(module, source=module_dir)``, raising AgentError when the module does not fit where it
            will act; None checks nothing.
    """
    module_dir = resolve_module_dir(target, policy=policy)
    module = _load_module(module_dir)
    if check is not None:
        check(module, source=str(module_dir))
    return module


def load_rllib_policy(target: str, *, policy: str = "default_policy",
                      check: Callable[..., None] | None) -> tuple[Any, ConnectorPipelines | None]:
    """Loads the RLModule and, from an algorithm checkpoint, its connector pipelines (no Ray cluster).

    Args:
        target: What ``rllib:PATH`` names (module docstring).
        policy: Module id inside an algorithm checkpoint.
        check: ``check(module, source=module_dir, observation_space=space)``, raising AgentError when the policy
            does not fit where it will act; ``space`` is what the agent takes: the pipeline's input space, or the
            module's own. None checks nothing.

    Returns:
        The module and the restored pipelines (None: a bare module, or a checkpoint without pipelines).
    """
    module_dir, checkpoint = resolve_checkpoint(target, policy=policy)
    module = _load_module(module_dir)
    folder = pipelines_dir(checkpoint) if checkpoint is not None else None
    pipelines = load_pipelines(folder, source=str(checkpoint)) if folder is not None else None
    if check is not None:
        space = pipelines.input_observation_space if pipelines is not None else module.observation_space
        check(module, source=str(module_dir), observation_space=space)
    return module, pipelines


def _load_module(module_dir: Path) -> Any:
    from dsage_ray.agents.rllib_module import drop_rlmodule_config_warning

    cls = module_class(module_dir)
    drop_rlmodule_config_warning()  # also when the recorded class comes from a package that does not install it
    try:
        module = cls.from_checkpoint(module_dir.resolve())  # relative paths read as URIs without a scheme
    except Exception as exc:  # noqa: BLE001 - missing/corrupt state files surface as many types
        raise AgentError(f"rllib checkpoint {str(module_dir)!r}: cannot load the module ({describe_exception(exc)})") from None
    return module


def load_rllib(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
               action_space: gymnasium.Space) -> tuple[RLlibAgent, str]:
    """The agent ``rllib:PATH[?policy=NAME&greedy=0|1&normalize_actions=0|1]`` names, its spaces checked against
    the environment's, and the label its errors start with."""
    policy = options.get_str("policy", "default_policy")
    greedy = options.get_bool("greedy", False)
    labels = []

    def check_env_spaces(module: Any, *, source: str, observation_space: Any) -> None:
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
    return RLlibAgent(module=module, greedy=greedy, normalize_actions=normalize, pipelines=pipelines), labels[0]
