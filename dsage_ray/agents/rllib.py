"""RLlib policies (``rllib:PATH``): an RLModule from a new-API-stack checkpoint, run batched in our simulator.

``PATH`` may be

* an RLlib **algorithm checkpoint** folder (what ``algo.save_to_path`` writes); the module is read from
  ``learner_group/learner/rl_module/<policy>``;
* an **RLModule** checkpoint folder (that sub-folder, or what ``module.save_to_path`` writes);
* the name of an agent shipped with the package under ``dsage_ray/assets/agents/`` (``rllib:ppo_maze``),
  used when no folder of that name exists.

Only the module is loaded (``RLModule.from_checkpoint``): no Ray cluster starts and no env runner is built.
The module's class is stored in the checkpoint by import path, so it must be importable here; the project's
own :class:`~dsage_ray.agents.rllib_module.MazeRLModule` always is. Any ``TorchRLModule`` works if its
observation space is the Maze's ``Dict(direction=Discrete(4), image=Box(0, 255, (5, 5, 3), uint8))`` and
its action space ``Discrete(k)``, ``k <= 7``.

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
from dsage_ray.agents.sampling import sample_from_logits

#: Where an algorithm checkpoint keeps its modules (``<ckpt>/<this>/<module id>``).
MODULES_SUBDIR = Path("learner_group") / "learner" / "rl_module"
_CTOR_FILE = "class_and_ctor_args.pkl"


class RLlibAgent(Agent):
    """A loaded RLModule as a batched agent; state is ``None`` or the module's state dict of ``(n, ...)`` tensors.

    Args:
        module: A ``TorchRLModule`` whose spaces match the Maze (checked by :func:`check_spaces`).
        greedy: Argmax instead of sampling.
    """

    def __init__(self, *, module: Any, greedy: bool = False) -> None:
        self.module = module.eval()
        self.greedy = greedy
        initial = module.get_initial_state() if hasattr(module, "get_initial_state") else {}
        #: One episode's initial state, as tensors; empty for a feed-forward module.
        self._initial = {k: torch.as_tensor(np.asarray(v)) for k, v in (initial or {}).items()}

    @property
    def recurrent(self) -> bool:
        return bool(self._initial)

    def initial_state(self, batch_size: int) -> AgentState:
        if not self.recurrent:
            return None
        return {k: v.unsqueeze(0).repeat(batch_size, *([1] * v.dim())) for k, v in self._initial.items()}

    def logits(self, obs: Observation, state: AgentState) -> tuple[torch.Tensor, AgentState]:
        """One module step: logits ``(n, k)`` and the next state; no sampling."""
        from ray.rllib.core.columns import Columns

        image = torch.from_numpy(np.ascontiguousarray(obs["image"]))
        direction = torch.from_numpy(np.asarray(obs["direction"], dtype=np.int64))
        if self.recurrent:
            # RLlib's env-to-module connector adds a time axis of 1 for stateful modules; so do we.
            batch = {Columns.OBS: {"direction": direction[:, None], "image": image[:, None]}, Columns.STATE_IN: state}
        else:
            batch = {Columns.OBS: {"direction": direction, "image": image}}
        with torch.inference_mode():
            out = self.module.forward_exploration(batch) if not self.greedy else self.module.forward_inference(batch)
        logits = out[Columns.ACTION_DIST_INPUTS]
        if self.recurrent:
            return logits[:, 0], out[Columns.STATE_OUT]
        return logits, None

    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        logits, state = self.logits(obs, state)
        if self.greedy:
            return logits.argmax(dim=-1).numpy().astype(np.int64), state
        return sample_from_logits(logits, rng), state


def resolve_module_dir(target: str, *, policy: str = "default_policy") -> Path:
    """The RLModule folder that ``target`` names (module docstring); AgentError when there is none."""
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
                return modules / policy
            found = sorted(p.name for p in modules.iterdir() if p.is_dir())
            raise AgentError(f"rllib checkpoint {str(path)!r}: no module {policy!r} (modules: "
                             f"{', '.join(found) or 'none'}); pick one with ?policy=NAME")
    if (path / _CTOR_FILE).is_file():
        return path
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


def check_spaces(module: Any, *, source: str) -> None:
    """AgentError unless the module observes the Maze's dict observation and acts in ``Discrete(k <= 7)``."""
    import gymnasium as gym

    space = module.observation_space
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
    """Loads only the RLModule a checkpoint holds (no Ray cluster), with its spaces checked.

    Args:
        target: What ``rllib:PATH`` names (module docstring).
        policy: Module id inside an algorithm checkpoint.
        check: ``check(module, source=module_dir)``, raising AgentError when the module does not fit where it
            will act: by default :func:`check_spaces` (the Maze's spaces); None checks nothing.
    """
    from dsage_ray.agents.rllib_module import drop_rlmodule_config_warning

    module_dir = resolve_module_dir(target, policy=policy)
    cls = module_class(module_dir)
    drop_rlmodule_config_warning()  # also when the recorded class comes from a package that does not install it
    try:
        module = cls.from_checkpoint(module_dir.resolve())  # relative paths read as URIs without a scheme
    except Exception as exc:  # noqa: BLE001 - missing/corrupt state files surface as many types
        raise AgentError(f"rllib checkpoint {str(module_dir)!r}: cannot load the module ({describe_exception(exc)})") from None
    if check is not None:
        check(module, source=str(module_dir))
    return module


def load_rllib_agent(target: str, options: SpecOptions) -> RLlibAgent:
    """Factory for ``rllib:PATH[?policy=NAME&greedy=0|1]``."""
    policy = options.get_str("policy", "default_policy")
    greedy = options.get_bool("greedy", False)
    return RLlibAgent(module=load_rllib_module(target, policy=policy), greedy=greedy)
