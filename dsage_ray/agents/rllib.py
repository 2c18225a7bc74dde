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
own :class:`~dsage_ray.agents.rllib_module.MazeRLModule` always is. Any ``TorchRLModule`` works if its
observation space (or its pipeline's input space) is the Maze's ``Dict(direction=Discrete(4), image=Box(0, 255,
(5, 5, 3), uint8))`` and its action space ``Discrete(k)``, ``k <= 7``.

Recurrent modules (a non-empty ``get_initial_state()``) get RLlib's inference layout: a time axis of
length 1 on every input, ``STATE_IN`` in, ``STATE_OUT`` out. Actions are sampled from
``softmax(ACTION_DIST_INPUTS)`` with the caller's numpy ``rng`` (never torch's), so evaluations are
reproducible from their seed.

Options (``rllib:PATH?policy=default_policy&greedy=0``):
    policy: Module id inside an algorithm checkpoint (default ``default_policy``).
    greedy: 1 takes the argmax action instead of sampling (default 0).
"""

from __future__ import annotations

import io
import pickle
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.constants import NUM_ACTIONS, OBSERVATION_SPACE
from dsage_ray.agents.loader import (SpecOptions, describe_exception, local_path, shipped_agent_dir,
                                     shipped_agent_names)
from dsage_ray.agents.rllib_connectors import ConnectorPipelines, EpisodeState, load_pipelines, pipelines_dir
from dsage_ray.agents.sampling import sample_from_logits

#: Where an algorithm checkpoint keeps its modules (``<ckpt>/<this>/<module id>``).
MODULES_SUBDIR = Path("learner_group") / "learner" / "rl_module"
_CTOR_FILE = "class_and_ctor_args.pkl"


class RLlibAgent(Agent):
    """A loaded RLModule as a batched agent.

    State: ``None`` or the module's state dict of ``(n, ...)`` tensors; behind connector pipelines, an
    :class:`~dsage_ray.agents.rllib_connectors.EpisodeState` (one RLlib episode per running episode, which also
    holds a recurrent module's state, as in RLlib's env runner).

    Args:
        module: A ``TorchRLModule`` whose spaces match the Maze (checked by :func:`check_spaces`).
        greedy: Argmax instead of sampling.
        pipelines: The checkpoint's restored connector pipelines, or None. Pipelines of RLlib's default pieces
            only (no ``transforms``) act as the direct path does, which is then kept.
    """

    def __init__(self, *, module: Any, greedy: bool = False, pipelines: ConnectorPipelines | None = None) -> None:
        self.module = module.eval()
        self.greedy = greedy
        self.pipelines = pipelines if pipelines is not None and pipelines.transforms else None
        initial = module.get_initial_state() if hasattr(module, "get_initial_state") else {}
        #: One episode's initial state, as tensors; empty for a feed-forward module.
        self._initial = {k: torch.as_tensor(np.asarray(v)) for k, v in (initial or {}).items()}

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

    def logits(self, obs: Observation, state: AgentState) -> tuple[torch.Tensor, AgentState]:
        """One module step: logits ``(n, k)`` and the next state; no sampling."""
        from ray.rllib.core.columns import Columns

        if self.pipelines is not None:
            return self.piped_step(obs, state)
        image = torch.from_numpy(np.ascontiguousarray(obs["image"]))
        direction = torch.from_numpy(np.asarray(obs["direction"], dtype=np.int64))
        if self.recurrent:
            # RLlib's env-to-module connector adds a time axis of 1 for stateful modules; so do we.
            batch = {Columns.OBS: {"direction": direction[:, None], "image": image[:, None]}, Columns.STATE_IN: state}
        else:
            batch = {Columns.OBS: {"direction": direction, "image": image}}
        out = self.forward(batch)
        logits = out[Columns.ACTION_DIST_INPUTS]
        if self.recurrent:
            return logits[:, 0], out[Columns.STATE_OUT]
        return logits, None

    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        logits, state = self.logits(obs, state)
        if self.greedy:
            actions = logits.argmax(dim=-1).numpy().astype(np.int64)
        else:
            actions = sample_from_logits(logits, rng)
        return actions, (state.acted(actions) if isinstance(state, EpisodeState) else state)


def resolve_module_dir(target: str, *, policy: str = "default_policy") -> Path:
    """The RLModule folder that ``target`` names (module docstring); AgentError when there is none."""
    return resolve_checkpoint(target, policy=policy)[0]


def resolve_checkpoint(target: str, *, policy: str = "default_policy") -> tuple[Path, Path | None]:
    """The RLModule folder that ``target`` names and the algorithm checkpoint it lies in (None for a bare module)."""
    path = shipped_agent_dir(target) or Path(local_path(target)).expanduser()
    if not path.exists():
        shipped = shipped_agent_names(holding=_CTOR_FILE)
        raise AgentError(f"rllib checkpoint {str(path)!r}: not found"
                         + (f" (shipped agents: {', '.join(shipped)})" if shipped else ""))
    if not path.is_dir():
        raise AgentError(f"rllib checkpoint {str(path)!r}: not a folder (expected an RLlib algorithm "
                         f"or RLModule checkpoint folder)")
    # An algorithm (or learner) checkpoint has its own class file at the top: look for modules first.
    for modules in (path / MODULES_SUBDIR, path / "rl_module"):
        if modules.is_dir():
            if (modules / policy / _CTOR_FILE).is_file():
                return modules / policy, (path if modules == path / MODULES_SUBDIR else None)
            found = sorted(p.name for p in modules.iterdir() if p.is_dir())
            raise AgentError(f"rllib checkpoint {str(path)!r}: no module {policy!r} (modules: "
                             f"{', '.join(found) or 'none'}); pick one with ?policy=NAME")
    if (path / _CTOR_FILE).is_file():
        return path, None
    raise AgentError(f"rllib checkpoint {str(path)!r}: not an RLlib checkpoint (no {_CTOR_FILE} and no "
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
        info = _RecordingUnpickler(io.BytesIO((module_dir / _CTOR_FILE).read_bytes())).load()
    except AgentError as exc:
        raise AgentError(f"rllib checkpoint {source!r}: module {exc}; install or put on PYTHONPATH the package "
                         f"that defines it") from None
    except Exception as exc:  # noqa: BLE001 - a corrupt pickle raises anything
        raise AgentError(f"rllib checkpoint {source!r}: unreadable {_CTOR_FILE} ({describe_exception(exc)})") from None
    cls = info.get("class") if isinstance(info, dict) else None
    from ray.rllib.core.rl_module.torch import TorchRLModule

    if not (isinstance(cls, type) and issubclass(cls, TorchRLModule)):
        raise AgentError(f"rllib checkpoint {source!r}: holds {cls!r}, not a TorchRLModule")
    return cls


def check_spaces(module: Any, *, source: str, observation_space: Any = None) -> None:
    """AgentError unless the module observes the Maze's dict observation and acts in ``Discrete(k <= 7)``.

    ``observation_space``: what the agent takes, where that is not the module's own space (a pipeline's input).
    """
    import gymnasium as gym

    space = module.observation_space if observation_space is None else observation_space
    expected = OBSERVATION_SPACE
    ok = (isinstance(space, gym.spaces.Dict) and set(space.spaces) == set(expected.spaces)
          and isinstance(space["image"], gym.spaces.Box) and space["image"].shape == expected["image"].shape
          and isinstance(space["direction"], gym.spaces.Discrete) and space["direction"].n == expected["direction"].n)
    if not ok:
        raise AgentError(f"rllib checkpoint {source!r}: observation space {space} does not match the maze observation "
                         f"{expected}")
    actions = module.action_space
    if not (isinstance(actions, gym.spaces.Discrete) and 1 <= actions.n <= NUM_ACTIONS):
        raise AgentError(f"rllib checkpoint {source!r}: action space {actions} is not Discrete(k), k <= {NUM_ACTIONS}")


def load_rllib_module(target: str, *, policy: str = "default_policy",
                      check: Callable[..., None] | None = check_spaces):
    """Loads only the RLModule a checkpoint holds (no Ray cluster, no connector pipelines), with its spaces checked.

    Args:
        target: What ``rllib:PATH`` names (module docstring).
        policy: Module id inside an algorithm checkpoint.
        check: ``check(module, source=module_dir)``, raising AgentError when the module does not fit where it
            will act: by default :func:`check_spaces` (the Maze's spaces); None checks nothing.
    """
    module_dir = resolve_module_dir(target, policy=policy)
    module = _load_module(module_dir)
    if check is not None:
        check(module, source=str(module_dir))
    return module


def load_rllib_policy(target: str, *, policy: str = "default_policy",
                      check: Callable[..., None] | None = check_spaces) -> tuple[Any, ConnectorPipelines | None]:
    """Loads the RLModule and, from an algorithm checkpoint, its connector pipelines (no Ray cluster).

    Args:
        target: What ``rllib:PATH`` names (module docstring).
        policy: Module id inside an algorithm checkpoint.
        check: ``check(module, source=module_dir, observation_space=space)``, raising AgentError when the policy
            does not fit where it will act; ``space`` is what the agent takes: the pipeline's input space, or the
            module's own. By default :func:`check_spaces` (the Maze's spaces); None checks nothing.

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


def load_rllib_agent(target: str, options: SpecOptions) -> RLlibAgent:
    """Factory for ``rllib:PATH[?policy=NAME&greedy=0|1]``."""
    policy = options.get_str("policy", "default_policy")
    greedy = options.get_bool("greedy", False)
    module, pipelines = load_rllib_policy(target, policy=policy)
    return RLlibAgent(module=module, greedy=greedy, pipelines=pipelines)
