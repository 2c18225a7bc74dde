"""Stable-Baselines3's files read as data: a save's ``data`` entry and ``VecNormalize`` statistics, without running code.

An SB3 ``.zip`` stores its constructor arguments as JSON, with every object JSON cannot hold (the policy class, the
spaces, the schedules, numpy arrays) as a base64 cloudpickle. SB3's own loader unpickles them, which runs whatever
the file names, and fails on SB3 1.x saves whose spaces are ``gym``'s (``No module named 'gym'``). Here each pickle
is read with the allowlist reader (:mod:`dsage_ray.safe_pickle`), which resolves only:

* the SB3 and sb3-contrib policy classes, torch's activation and optimiser classes and SB3's feature extractors
  (what ``policy_class`` and ``policy_kwargs`` name), ``torch.device`` and SB3's ``TrainFreq``;
* stand-ins (:class:`Recorded`) for spaces, ``VecNormalize`` and ``RunningMeanStd``: an object's class name and
  state, with none of its code called.

The schedules, the action noise and the replay buffer's class are replaced, not read (a policy does not use them);
anything else that does not read as data is training state and is dropped. :func:`read_save` gives what SB3's
loader takes as ``custom_objects``, so that it unpickles nothing; the weights are ``torch.load(weights_only=True)``.
"""

from __future__ import annotations

import base64
import importlib
import json
import pickle
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.loader import describe_exception
from dsage_ray import safe_pickle

#: Keys a policy does not use, given fixed values instead of being read (schedules are cloudpickled functions).
REPLACED_KEYS: dict[str, Any] = {
    "learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0, "clip_range_vf": None,
    "exploration_schedule": lambda _: 0.0, "action_noise": None, "replay_buffer_class": None,
    "replay_buffer_kwargs": {}, "rollout_buffer_class": None, "rollout_buffer_kwargs": {},
    "buffer_size": 1,  # off-policy loads allocate their replay buffer: one transition, not a million
}
#: Keys without which a policy cannot be built: one that does not read as data refuses the save.
REQUIRED_KEYS = ("policy_class", "policy_kwargs", "observation_space", "action_space")
#: Modules whose classes ``policy_class`` and ``policy_kwargs`` may name (prefixes), and the base they must have.
_CLASS_MODULES = ("stable_baselines3.", "sb3_contrib.", "torch.nn.modules.activation", "torch.optim.")
#: Modules of the third-party objects read as :class:`Recorded` stand-ins.
_RECORDED_MODULES = ("gym.spaces.", "gymnasium.spaces.", "stable_baselines3.common.vec_env.vec_normalize",
                     "stable_baselines3.common.running_mean_std")


class Recorded:
    """A third-party object as data: its class's ``module.name`` and the state its pickle holds; no code of it ran."""

    kind = ""

    def __init__(self, *args: Any) -> None:
        self.args = args
        self.state: Any = {}

    def __setstate__(self, state: Any) -> None:
        self.state = state

    def get(self, key: str, default: Any = None) -> Any:
        """A key of the recorded state (``__dict__`` or a ``(dict, slots)`` pair); gym's spaces keep some of theirs
        under a leading underscore (``_shape``), Gymnasium's all."""
        state = self.state[0] if isinstance(self.state, tuple) and self.state else self.state
        return state.get(key, default) if isinstance(state, dict) else default


def _recorded_class(module: str, name: str) -> type:
    return type(name, (Recorded,), {"kind": f"{module}.{name}"})


def _resolve(module: str, name: str) -> Any:
    """What an SB3 pickle may name beyond the allowlist (module docstring); None refuses it."""
    if module.startswith(_RECORDED_MODULES) and name.isidentifier():
        return _recorded_class(module, name)
    if (module, name) == ("torch", "device"):  # some zoo saves keep device=torch.device("cpu") in policy_kwargs
        import torch

        return torch.device
    if not module.startswith(_CLASS_MODULES) or not name.isidentifier():
        return None
    try:
        found = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError):
        return None
    import enum

    import torch
    from stable_baselines3.common.policies import BasePolicy
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
    from stable_baselines3.common.type_aliases import TrainFreq

    data_classes = (BasePolicy, BaseFeaturesExtractor, torch.nn.Module, torch.optim.Optimizer)
    if isinstance(found, type) and (issubclass(found, data_classes) or found is TrainFreq
                                    or (issubclass(found, enum.Enum) and module.startswith("stable_baselines3."))):
        return found
    return None


def unpickle(blob: bytes, *, what: str) -> Any:
    """One SB3 pickle read as data (:func:`_resolve`); UnsafePickleError names what it refused."""
    return safe_pickle.loads(blob, also=_resolve, what=what)


@dataclass
class Save:
    """An SB3 save read as data.

    Attributes:
        path: The zip.
        data: Its ``data`` entry: plain JSON values, and the pickled ones read as data (spaces as :class:`Recorded`).
        custom_objects: What SB3's ``load`` takes for every pickled entry, so that it unpickles none.
        sb3_version: The ``_stable_baselines3_version`` it was written by ("" if absent).
        keys: Every key of the ``data`` entry, the replaced ones included.
    """

    path: Path
    data: dict[str, Any]
    custom_objects: dict[str, Any] = field(default_factory=dict)
    sb3_version: str = ""
    keys: frozenset[str] = frozenset()

    @property
    def policy_module(self) -> str:
        policy = self.data.get("policy_class")
        return getattr(policy, "__module__", "") or ""


def read_save(path: Path, *, label: str) -> Save:
    """Reads an SB3 ``.zip`` without running anything it holds (module docstring).

    Raises:
        AgentError: Not a zip or not an SB3 save, or a required entry (policy class, spaces) that names code.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            raw = json.loads(archive.read("data"))
            names = archive.namelist()
            version = (archive.read("_stable_baselines3_version").decode(errors="replace").strip()
                       if "_stable_baselines3_version" in names else "")
    except zipfile.BadZipFile:
        head = path.read_bytes()[:64]
        what = ("an empty file" if not head else "a Git LFS pointer, not the file itself (git lfs pull)"
                if head.startswith(b"version https://git-lfs") else "not a zip file")
        raise AgentError(f"{label}: {what} (expected a Stable-Baselines3 .zip save)") from None
    except KeyError:
        raise AgentError(f"{label}: no 'data' entry in the zip (not a Stable-Baselines3 save)") from None
    except (OSError, ValueError) as exc:
        raise AgentError(f"{label}: unreadable Stable-Baselines3 save ({describe_exception(exc)})") from None
    if not isinstance(raw, dict):
        raise AgentError(f"{label}: its 'data' entry is not a JSON object (not a Stable-Baselines3 save)")
    save = Save(path=path, data={}, sb3_version=version, keys=frozenset(raw))
    for key, item in raw.items():
        if not (isinstance(item, dict) and ":serialized:" in item):
            save.data[key] = item
            continue
        if key in REPLACED_KEYS:
            save.custom_objects[key] = REPLACED_KEYS[key]
            continue
        try:
            value = unpickle(base64.b64decode(str(item[":serialized:"])), what="a Stable-Baselines3 save read as data")
        except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, ImportError) as exc:
            if key in REQUIRED_KEYS:
                raise AgentError(f"{label}: its {key!r} does not read as data ({describe_exception(exc)})") from None
            value = None  # training state (buffers, counters): a policy does not need it
        save.data[key] = value
        save.custom_objects[key] = value
    for key in REPLACED_KEYS:
        if key in save.data and key not in save.custom_objects:
            save.custom_objects[key] = REPLACED_KEYS[key]
    for key in ("observation_space", "action_space"):
        if not isinstance(save.data.get(key), (Recorded, gymnasium.Space)):
            raise AgentError(f"{label}: no {key.replace('_', ' ')} recorded (not a Stable-Baselines3 policy save)")
    return save


def recorded_space(value: Any) -> gymnasium.Space:
    """The Gymnasium space a recorded ``gym``/``gymnasium`` space describes (Box, Discrete, MultiDiscrete, MultiBinary,
    Dict, Tuple).

    Raises:
        AgentError: A space of another kind, or one whose recorded state is malformed.
    """
    if isinstance(value, gymnasium.Space):
        return value
    if not isinstance(value, Recorded):
        raise AgentError(f"a recorded space is a {type(value).__name__}, not a space")
    name = value.kind.rpartition(".")[2]
    try:
        if name == "Box":
            dtype = np.dtype(value.get("dtype", np.float32))
            return spaces.Box(low=np.asarray(value.get("low")), high=np.asarray(value.get("high")),
                              shape=tuple(value.get("shape", value.get("_shape"))), dtype=dtype)
        if name == "Discrete":
            return spaces.Discrete(int(value.get("n")), start=int(value.get("start", 0)))
        if name == "MultiDiscrete":
            return spaces.MultiDiscrete(np.asarray(value.get("nvec")))
        if name == "MultiBinary":
            return spaces.MultiBinary(value.get("n"))
        if name == "Dict":
            return spaces.Dict({key: recorded_space(sub) for key, sub in dict(value.get("spaces")).items()})
        if name == "Tuple":
            return spaces.Tuple(tuple(recorded_space(sub) for sub in value.get("spaces")))
    except AgentError:
        raise
    except Exception as exc:  # noqa: BLE001 - a malformed record fails in any way; name it
        raise AgentError(f"a recorded {value.kind} is malformed ({describe_exception(exc)})") from None
    raise AgentError(f"a recorded {value.kind} is not a space this loader reads (Box, Discrete, MultiDiscrete, "
                     f"MultiBinary, Dict, Tuple)")


@dataclass(frozen=True)
class ObservationStats:
    """``VecNormalize``'s observation statistics, applied as it does: ``clip((obs - mean) / sqrt(var + epsilon))``.

    Attributes:
        mean, var: Per observation entry (per key for a Dict observation).
        clip: The bound of the normalised observation.
        epsilon: Added to the variance.
        keys: Which keys of a Dict observation are normalised (None: the observation is an array).
    """

    mean: Any
    var: Any
    clip: float
    epsilon: float
    keys: tuple[str, ...] | None = None

    def apply(self, obs: Any) -> Any:
        """Normalises a batch (arrays ``(n, ...)``, or a dict of them)."""
        if self.keys is None:
            return self._one(obs, self.mean, self.var)
        return {key: self._one(value, self.mean[key], self.var[key]) if key in self.keys else value
                for key, value in obs.items()}

    def _one(self, obs: np.ndarray, mean: np.ndarray, var: np.ndarray) -> np.ndarray:
        normalised = (np.asarray(obs, np.float64) - mean) / np.sqrt(var + self.epsilon)
        return np.clip(normalised, -self.clip, self.clip).astype(np.float32)


def read_vecnormalize(path: Path, *, label: str) -> ObservationStats | None:
    """The observation statistics of a ``vecnormalize.pkl`` (None where it normalises no observation).

    Raises:
        AgentError: A file that does not read as data (it names code), or is not ``VecNormalize`` statistics.
    """
    try:
        loaded = unpickle(path.read_bytes(), what="VecNormalize statistics")
    except OSError as exc:
        raise AgentError(f"{label}: cannot read {str(path)!r} ({describe_exception(exc)})") from None
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, ImportError) as exc:
        raise AgentError(f"{label}: {str(path)!r} does not read as data ({describe_exception(exc)})") from None
    if not (isinstance(loaded, Recorded) and loaded.kind.endswith(".VecNormalize")):
        raise AgentError(f"{label}: {str(path)!r} holds a {getattr(loaded, 'kind', type(loaded).__name__)}, not "
                         f"VecNormalize statistics")
    if not loaded.get("norm_obs", True):
        return None
    rms = loaded.get("obs_rms")
    try:
        clip, epsilon = float(loaded.get("clip_obs", 10.0)), float(loaded.get("epsilon", 1e-8))
        if isinstance(rms, dict):  # a Dict observation: one RunningMeanStd per key
            keys = tuple(loaded.get("norm_obs_keys") or rms)
            mean = {k: np.asarray(rms[k].get("mean"), np.float64) for k in keys}
            var = {k: np.asarray(rms[k].get("var"), np.float64) for k in keys}
            return ObservationStats(mean=mean, var=var, clip=clip, epsilon=epsilon, keys=keys)
        mean, var = np.asarray(rms.get("mean"), np.float64), np.asarray(rms.get("var"), np.float64)
    except Exception as exc:  # noqa: BLE001 - a malformed record fails in any way; name it
        raise AgentError(f"{label}: {str(path)!r} holds malformed statistics ({describe_exception(exc)})") from None
    if mean.shape != var.shape or not (np.all(np.isfinite(mean)) and np.all(np.isfinite(var)) and np.all(var >= 0)):
        raise AgentError(f"{label}: {str(path)!r} holds malformed statistics (mean {mean.shape}, var {var.shape})")
    return ObservationStats(mean=mean, var=var, clip=clip, epsilon=epsilon)
