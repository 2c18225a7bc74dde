"""RL Baselines3 Zoo run folders: what the zoo trained an agent with, read as data.

A run folder, as the zoo writes it and DLR-RM/rl-trained-agents publishes it::

    ALGO/ENV_1/ENV.zip                 the Stable-Baselines3 model
    ALGO/ENV_1/ENV/config.yml          the hyper-parameters (normalize, frame_stack, env_wrapper, ...)
    ALGO/ENV_1/ENV/args.yml            the zoo's command line (algo, env, ...)
    ALGO/ENV_1/ENV/vecnormalize.pkl    VecNormalize statistics, where config.yml has ``normalize``
    ALGO/ENV_1/evaluations.npz         the returns of the zoo's evaluations during training

The zoo plays such an agent (its ``enjoy.py``) inside the environment wrappers of ``env_wrapper``, then normalises
observations with the saved statistics, then stacks ``frame_stack`` frames. :func:`read_run_folder` says what of that
applies, and refuses what cannot be applied as trained (a wrapper that is neither Gymnasium's nor SB3's, a
``vec_env_wrapper``) in one line naming it.

``config.yml`` and ``args.yml`` are YAML with a ``!!python/object/apply:collections.OrderedDict`` tag: they are read
with a safe loader that builds that one class and nothing else (any other ``!!python`` tag is refused, so a forged
file runs nothing). ``normalize`` may be a string of a Python dict (``"{'norm_obs': True, 'norm_reward': False}"`` or
``"dict(norm_obs=True, norm_reward=False)"``), parsed with :mod:`ast`, never ``eval``. ``evaluations.npz`` is read
with ``allow_pickle=False``.
"""

from __future__ import annotations

import ast
import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.loader import describe_exception
from dsage_ray.agents.sb3_files import ObservationStats, read_vecnormalize

#: The tag the zoo's YAML files carry (PyYAML's dump of an OrderedDict).
_ORDERED_DICT_TAG = "tag:yaml.org,2002:python/object/apply:collections.OrderedDict"
#: config.yml keys that change how the agent is played; every other key is a training hyper-parameter.
PLAY_KEYS = ("normalize", "frame_stack", "env_wrapper", "vec_env_wrapper")
#: Where an ``env_wrapper`` may come from: Gymnasium's and SB3's own wrappers (``gym.`` as written by SB3 1.x).
_WRAPPER_MODULES = ("gymnasium.wrappers", "gym.wrappers", "stable_baselines3.common.", "sb3_contrib.common.wrappers")

#: ``wrapper(env) -> env``.
EnvWrapper = Callable[[Any], Any]


class _ZooLoader(yaml.SafeLoader):
    """PyYAML's safe loader plus the zoo's OrderedDict tag (as a plain dict); nothing else is constructed."""


def _ordered_dict(loader: yaml.SafeLoader, node: yaml.Node) -> dict[str, Any]:
    pairs = loader.construct_sequence(node, deep=True)
    if len(pairs) != 1 or not isinstance(pairs[0], list):
        raise yaml.constructor.ConstructorError(None, None, "an OrderedDict tag without one list of pairs",
                                                node.start_mark)
    items = {}
    for pair in pairs[0]:
        if not (isinstance(pair, list) and len(pair) == 2 and isinstance(pair[0], str)):
            raise yaml.constructor.ConstructorError(None, None, f"an OrderedDict entry {pair!r} is not [key, value]",
                                                    node.start_mark)
        items[pair[0]] = pair[1]
    return items


_ZooLoader.add_constructor(_ORDERED_DICT_TAG, _ordered_dict)


def read_zoo_yaml(path: Path, *, label: str) -> dict[str, Any]:
    """A zoo ``config.yml``/``args.yml`` as a dict, built by the safe loader (module docstring).

    Raises:
        AgentError: Unreadable, not YAML, another ``!!python`` tag, or not a mapping.
    """
    try:
        loaded = yaml.load(path.read_text(), Loader=_ZooLoader)  # noqa: S506 - a SafeLoader subclass
    except OSError as exc:
        raise AgentError(f"{label}: cannot read {str(path)!r} ({describe_exception(exc)})") from None
    except yaml.YAMLError as exc:
        problem = str(getattr(exc, "problem", "") or exc).strip().splitlines()[0]
        raise AgentError(f"{label}: {str(path)!r} is not a zoo YAML file read as data ({problem}; nothing in it "
                         f"ran)") from None
    if loaded is None:
        return {}
    if not isinstance(loaded, dict):
        raise AgentError(f"{label}: {str(path)!r} holds a {type(loaded).__name__}, not a mapping")
    return loaded


@dataclass(frozen=True)
class RunFolder:
    """What a zoo run folder says about playing its agent.

    Attributes:
        model: The ``.zip`` to load.
        algo: The algorithm, from ``args.yml`` or the folder's parent (``ppo``), upper-case; "" if unknown.
        env_id: The environment the zoo trained in (``args.yml``), "" if unknown.
        normalization: The saved observation statistics, or None.
        frame_stack: Frames stacked (1: none).
        wrappers: The ``env_wrapper`` entries, as ``(import path, keyword arguments)``.
        expected_return: The mean return of the zoo's last evaluation, or None without ``evaluations.npz``.
    """

    model: Path
    algo: str
    env_id: str
    normalization: ObservationStats | None
    frame_stack: int
    wrappers: tuple[tuple[str, dict[str, Any]], ...]
    expected_return: float | None

    def env_wrappers(self, *, label: str) -> list[EnvWrapper]:
        """The wrappers as callables, imported from Gymnasium or SB3 (``gym.wrappers.X`` as ``gymnasium.wrappers.X``).

        Raises:
            AgentError: A wrapper that cannot be imported.
        """
        built = []
        for name, kwargs in self.wrappers:
            module, _, attr = ("gymnasium" + name[3:] if name.startswith("gym.") else name).rpartition(".")
            try:
                wrapper = getattr(importlib.import_module(module), attr)
            except (ImportError, AttributeError) as exc:
                raise AgentError(f"{label}: env_wrapper {name!r} cannot be imported ({describe_exception(exc)})") \
                    from None
            built.append(lambda env, wrapper=wrapper, kwargs=kwargs: wrapper(env, **kwargs))
        return built


def is_run_folder(path: Path) -> bool:
    """Whether ``path`` is a zoo run folder (a folder holding ``*/config.yml`` beside a ``.zip``)."""
    return path.is_dir() and any(path.glob("*/config.yml")) and any(path.glob("*.zip"))


def read_run_folder(folder: Path, *, label: str) -> RunFolder:
    """Reads a zoo run folder (module docstring).

    Raises:
        AgentError: No model or config, a ``normalize`` without its statistics, a wrapper that is neither Gymnasium's
            nor SB3's, a ``vec_env_wrapper``, or a file that does not read as data; one line each.
    """
    configs = sorted(folder.glob("*/config.yml"))
    if len(configs) != 1:
        raise AgentError(f"{label}: expected one ENV/config.yml in the run folder, found {len(configs)}")
    config_dir = configs[0].parent
    model = folder / f"{config_dir.name}.zip"
    if not model.is_file():
        zips = sorted(p.name for p in folder.glob("*.zip"))
        raise AgentError(f"{label}: no {model.name} beside {config_dir.name}/ (zips: {', '.join(zips) or 'none'})")
    config = read_zoo_yaml(configs[0], label=label)
    args_file = config_dir / "args.yml"
    args = read_zoo_yaml(args_file, label=label) if args_file.is_file() else {}
    if config.get("vec_env_wrapper"):
        raise AgentError(f"{label}: config.yml's vec_env_wrapper {config['vec_env_wrapper']!r} cannot be applied "
                         f"as trained (only env_wrapper, normalize and frame_stack are)")
    normalization = None
    normalize = _normalize_options(config.get("normalize", False), label=label)
    if normalize.get("norm_obs", True) and normalize:
        stats = config_dir / "vecnormalize.pkl"
        if not stats.is_file():
            raise AgentError(f"{label}: config.yml says normalize, but {str(stats)!r} is missing: the agent cannot be "
                             f"played as trained")
        normalization = read_vecnormalize(stats, label=label)
    frame_stack = config.get("frame_stack") or 1
    if not isinstance(frame_stack, int) or isinstance(frame_stack, bool) or frame_stack < 1:
        raise AgentError(f"{label}: config.yml's frame_stack {frame_stack!r} is not a positive integer")
    algo = str(args.get("algo") or folder.parent.name).upper().replace("-", "_")
    return RunFolder(model=model, algo=algo, env_id=str(args.get("env") or ""), normalization=normalization,
                     frame_stack=frame_stack, wrappers=_wrappers(config.get("env_wrapper"), label=label),
                     expected_return=_last_evaluation(folder / "evaluations.npz", label=label))


def _normalize_options(value: Any, *, label: str) -> dict[str, Any]:
    """config.yml's ``normalize`` as VecNormalize keywords: {} for off, ``{"norm_obs": ...}`` otherwise."""
    if isinstance(value, str):
        try:
            value = _literal(value)
        except (ValueError, SyntaxError):
            raise AgentError(f"{label}: config.yml's normalize {value!r} is not a literal (true, false, a dict or "
                             f"dict(key=literal, ...))") from None
    if value is True:
        return {"norm_obs": True}
    if not value:
        return {}
    if isinstance(value, dict):
        return {"norm_obs": True, **value}
    raise AgentError(f"{label}: config.yml's normalize {value!r} is not true, false or a dict")


def _literal(text: str) -> Any:
    """A Python literal, or ``dict(key=literal, ...)`` as the zoo writes ``normalize``; parsed, never evaluated."""
    tree = ast.parse(text.strip(), mode="eval").body
    if isinstance(tree, ast.Call) and isinstance(tree.func, ast.Name) and tree.func.id == "dict" and not tree.args:
        return {keyword.arg: ast.literal_eval(keyword.value) for keyword in tree.keywords if keyword.arg}
    return ast.literal_eval(tree)


def _wrappers(value: Any, *, label: str) -> tuple[tuple[str, dict[str, Any]], ...]:
    """``env_wrapper`` (a name, a ``{name: kwargs}`` or a list of either) as ``(name, kwargs)`` pairs."""
    if not value:
        return ()
    entries = value if isinstance(value, list) else [value]
    pairs = []
    for entry in entries:
        if isinstance(entry, dict) and len(entry) == 1:
            name, kwargs = next(iter(entry.items()))
            kwargs = kwargs or {}
        else:
            name, kwargs = entry, {}
        if not isinstance(name, str) or not isinstance(kwargs, dict):
            raise AgentError(f"{label}: config.yml's env_wrapper entry {entry!r} is not a name or {{name: kwargs}}")
        if not name.startswith(_WRAPPER_MODULES):
            raise AgentError(f"{label}: config.yml's env_wrapper {name!r} is neither Gymnasium's nor Stable-Baselines3's "
                             f"own, so it cannot be applied as trained")
        pairs.append((name, dict(kwargs)))
    return tuple(pairs)


def _last_evaluation(path: Path, *, label: str) -> float | None:
    """The mean return of the last row of ``evaluations.npz``'s ``results`` (evaluations × episodes), or None."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as npz:
            results = np.asarray(npz["results"], dtype=np.float64)
    except (OSError, KeyError, ValueError) as exc:
        raise AgentError(f"{label}: {str(path)!r} does not read as data ({describe_exception(exc)})") from None
    results = results.reshape(len(results), -1) if results.ndim else results  # (evaluations, episodes[, 1])
    if results.ndim != 2 or not results.size or not np.all(np.isfinite(results[-1])):
        raise AgentError(f"{label}: {str(path)!r} holds no finite evaluation returns (shape {results.shape})")
    return float(results[-1].mean())
