"""Agent specs: one string names a policy and how to load it, for the observation and action spaces it acts in.

A spec is ``KIND:TARGET[?OPTION=VALUE&OPTION=VALUE...]`` (or a bare ``KIND`` that takes no target,
:data:`BARE_KINDS`), for example::

    random
    rllib:ppo_cartpole
    sb3:runs/ppo_lunar.zip?greedy=1
    dcd:checkpoints/model_20000.tar?heading_quirk=1&quirk_group=10      (a kind the Maze registers)

The text after the last ``?`` holds the options (URL-query style); each kind documents its own, and an
option a kind does not use is an error rather than silently ignored.

A domain loads an agent with :func:`load_agent`, passing the spaces it acts in (the gym domain its environment's,
the Maze MiniGrid's) and the kinds it registers itself (the Maze's ``builtin``, ``dcd``; a domain's own
convention for a kind replaces the generic one for that domain). A kind maps the prefix to a factory
``factory(target, options, *, observation_space, action_space, env=None) -> Agent`` that checks the agent against
those spaces (:data:`AgentFactory`). Kinds come from, first to last: :func:`register_agent_kind` (this process
only: tests, notebooks), the domain's own, the entry-point group :data:`ENTRY_POINT_GROUP` (``dsage_ray.agents``)
of installed packages, and dsage_ray's own generic kinds (:data:`dsage_ray.agent_registry.BUILTIN_KINDS`:
``python``, ``random``, ``rllib``, ``sb3``, ``torchscript``, in :mod:`dsage_ray.agents.kinds`). A package adds a
kind so::

    [project.entry-points."dsage_ray.agents"]
    mykind = "my_package.agents:load_my_agent"

A factory of two arguments, ``factory(target, options)``, is still called that way (the spaces are not passed):
plug-ins written before the spaces were passed keep working. Because entry points are read from the installed
packages' metadata, a kind from an installed package is known in every process of the environment, Ray's
simulator actors included. Only the kind a spec names is imported (listing kinds imports nothing: ``random``
never imports torch).

Agents shipped with the package live in :data:`ASSETS_DIR`, one folder each, and a kind loads one by its
bare folder name (``dcd:accel``, ``rllib:ppo_maze``; :func:`shipped_agent_dir`). A folder may list its files'
sha256 in ``SHA256SUMS`` (``sha256sum`` format); :func:`verified_files` checks them on every load, so a
corrupted install fails with one clear line instead of loading wrong weights.
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
import pathlib
import re
from importlib import metadata
from typing import Any, Callable, Mapping, Union

from dsage_ray import agent_registry, plugins
# The kinds' table lives below the domains (the domain registry lists it): re-exported here.
from dsage_ray.agent_registry import ENTRY_POINT_GROUP, agent_kinds, register_agent_kind
from dsage_ray.agents.base import Agent, AgentError

#: ``factory(target, options, *, observation_space, action_space, env=None) -> Agent``; it reads its options
#: through :class:`SpecOptions` and checks the agent against the spaces. ``factory(target, options)`` (no spaces)
#: is still called so.
AgentFactory = Callable[..., Agent]
#: Kinds a spec may name without a target.
BARE_KINDS: tuple[str, ...] = ("random",)

#: Kinds whose loading runs code the file brings: RLlib checkpoints (pickles), TorchScript programs and ``python:``
#: modules. The others load data (``dcd:`` weights with ``weights_only``, ``sb3:`` saves and zoo folders through the
#: allowlist reader, :mod:`dsage_ray.agents.sb3_files`) or nothing (``builtin:``, ``random``, Mario's ``astar``). A
#: plug-in kind is code the user installed.
KINDS_RUNNING_CODE: tuple[str, ...] = ("rllib", "torchscript", "python")
#: One line for help texts and the docs.
RUNS_CODE_NOTE = ("loading rllib, torchscript and python agents runs their code: use only files you trust "
                  "(docs/TRUST.md)")
#: ``{path as a spec names it: the copy of it this process reads}``, filled by :mod:`dsage_ray.agents.shipping`.
LOCAL_COPIES: dict[str, str] = {}
#: Agents shipped inside the package, one folder each (module docstring).
ASSETS_DIR = pathlib.Path(__file__).resolve().parent.parent / "assets" / "agents"
#: A shipped agent folder's checksum file, in ``sha256sum`` format (``<hex>  <file name>`` per line).
CHECKSUMS_FILE = "SHA256SUMS"


class SpecOptions:
    """The ``?key=value&...`` options of a spec, read with type conversion and checked for leftovers."""

    def __init__(self, *, spec: str, items: dict[str, str]) -> None:
        self._spec = spec
        self._items = dict(items)
        self._used: set[str] = set()

    @property
    def spec(self) -> str:
        """The whole spec these options came from (for error messages)."""
        return self._spec

    def get_str(self, name: str, default: str) -> str:
        self._used.add(name)
        return self._items.get(name, default)

    def get_int(self, name: str, default: int, *, minimum: int | None = None, maximum: int | None = None) -> int:
        raw = self.get_str(name, str(default))
        try:
            value = int(raw)
        except ValueError:
            raise AgentError(f"agent spec {self._spec!r}: option {name}={raw!r} is not an integer") from None
        if minimum is not None and value < minimum:
            raise AgentError(f"agent spec {self._spec!r}: option {name}={value} must be >= {minimum}")
        if maximum is not None and value > maximum:
            raise AgentError(f"agent spec {self._spec!r}: option {name}={value} must be <= {maximum}")
        return value

    def get_bool(self, name: str, default: bool) -> bool:
        raw = self.get_str(name, "1" if default else "0").lower()
        if raw in ("1", "true", "yes", "on"):
            return True
        if raw in ("0", "false", "no", "off"):
            return False
        raise AgentError(f"agent spec {self._spec!r}: option {name}={raw!r} is not a boolean (use 0 or 1)")

    def check_all_used(self) -> None:
        unused = sorted(set(self._items) - self._used)
        if unused:
            raise AgentError(f"agent spec {self._spec!r}: unknown option(s) {', '.join(unused)}")


def _factory(kind: str, spec: str, own: Mapping[str, Union[str, AgentFactory]]) -> AgentFactory | None:
    """The factory of ``kind``: registered in this process, else the domain's ``own``, else from an entry point,
    else built in."""
    if kind in agent_registry.REGISTERED:
        return _resolve(agent_registry.REGISTERED[kind])
    if kind in own:
        return _resolve(own[kind])
    found = agent_registry.installed_kinds()
    if kind in found.clashes:
        providers = ", ".join(sorted(plugins.describe(entry) for entry in found.clashes[kind]))
        raise AgentError(f"agent spec {spec!r}: kind {kind!r} is provided by more than one installed package: "
                         f"{providers}; uninstall all but one")
    entry = found.points.get(kind)
    if entry is not None:
        try:
            factory = entry.load()
        except Exception as exc:  # noqa: BLE001 - a plug-in's import can fail in any way; say whose it is.
            raise AgentError(f"agent spec {spec!r}: kind {kind!r} ({entry.value}, from {_provider(entry)}) cannot be "
                             f"loaded: {describe_exception(exc)}") from None
        if not callable(factory):
            raise AgentError(f"agent spec {spec!r}: kind {kind!r} ({entry.value}, from {_provider(entry)}) is not a "
                             f"callable factory(target, options)")
        return factory
    if kind in agent_registry.BUILTIN_KINDS:
        return _resolve(agent_registry.BUILTIN_KINDS[kind])
    return None


def _provider(entry: metadata.EntryPoint) -> str:
    name = plugins.provider(entry)
    return f"package {name}" if name else "an installed package"


def parse_spec(spec: str) -> tuple[str, str, SpecOptions]:
    """Splits ``KIND:TARGET?options`` into its parts; raises :class:`AgentError` on malformed specs."""
    if spec.strip() in BARE_KINDS:
        return spec.strip(), "", SpecOptions(spec=spec, items={})
    kind, sep, rest = spec.partition(":")
    if not sep or not kind or not rest:
        raise AgentError(f"agent spec {spec!r}: expected KIND:TARGET, e.g. builtin:random or dcd:PATH")
    target, qsep, query = rest.rpartition("?") if "?" in rest else (rest, "", "")
    items: dict[str, str] = {}
    for pair in filter(None, query.split("&")):
        key, eq, value = pair.partition("=")
        if not eq or not key:
            raise AgentError(f"agent spec {spec!r}: option {pair!r} is not KEY=VALUE")
        if key in items:
            raise AgentError(f"agent spec {spec!r}: option {key!r} given twice")
        items[key] = value
    if not target:
        raise AgentError(f"agent spec {spec!r}: empty target after {kind}:")
    return kind, target, SpecOptions(spec=spec, items=items)


def load_agent(spec: str, *, observation_space: Any, action_space: Any, env: Any = None,
               kinds: Mapping[str, Union[str, AgentFactory]] | None = None) -> Agent:
    """Loads the agent a spec names, checked by its kind's factory against the spaces it will act in.

    Args:
        spec: ``KIND:TARGET[?options]`` (or a bare ``random``); kinds: the domain's own (``kinds``), dsage_ray's
            generic ones (``python``, ``random``, ``rllib``, ``sb3``, ``torchscript``), those of installed packages
            (entry-point group ``dsage_ray.agents``) and any registered in this process.
        observation_space: The environment's (single-episode) observation space.
        action_space: The environment's (single-episode) action space.
        env: The environment itself, for agents played inside training-time wrappers (an RL Zoo folder's
            ``env_wrapper``); without it such an agent is refused.
        kinds: The calling domain's own kinds, ``{kind: factory or "module:function"}``; for that domain they
            replace a generic kind of the same name (the Maze's ``torchscript`` convention).

    Returns:
        The agent, with ``agent.spec`` set to ``spec``; it acts on
        :func:`~dsage_ray.agents.spaces.stack_observations` batches of the environment as
        :meth:`Agent.wrap_env` wraps it.

    Raises:
        AgentError: Unknown kind, unknown option, a target that cannot be loaded, or an agent that does not fit
            the spaces; the message is one line naming the spec or file and the problem.
    """
    kind, target, options = parse_spec(spec)
    own = dict(kinds or {})
    factory = _factory(kind, spec, own)
    if factory is None:
        known = ", ".join(sorted({*own, *agent_kinds()}))
        raise AgentError(f"agent spec {spec!r}: unknown kind {kind!r} (known: {known}; installed packages add kinds "
                         f"through the {ENTRY_POINT_GROUP!r} entry-point group)")
    if _takes_spaces(factory):
        agent = factory(target, options, observation_space=observation_space, action_space=action_space, env=env)
    else:
        agent = factory(target, options)
    options.check_all_used()
    agent.spec = spec
    return agent


def _takes_spaces(factory: Callable[..., Any]) -> bool:
    """Whether ``factory`` takes the spaces as keywords (a two-argument factory predates them)."""
    try:
        parameters = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):  # a builtin or C callable without a signature: the old call
        return False
    names = {p.name for p in parameters if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    return "observation_space" in names or any(p.kind is p.VAR_KEYWORD for p in parameters)


def _resolve(factory: Union[str, AgentFactory]) -> AgentFactory:
    if callable(factory):
        return factory
    module_name, _, attr = factory.partition(":")
    return getattr(importlib.import_module(module_name), attr)


def local_path(target: str) -> str:
    """Where this process reads the path ``target`` names: the copy :mod:`dsage_ray.agents.shipping` unpacked here
    (a Ray actor on another node), else ``target`` itself."""
    return LOCAL_COPIES.get(target, target)


def require_file(path: str, *, what: str) -> pathlib.Path:
    """Returns ``path`` (or its :func:`local_path` copy) as a :class:`pathlib.Path` if it is a readable file, else
    raises :class:`AgentError`."""
    p = pathlib.Path(local_path(path)).expanduser()
    if not p.exists():
        raise AgentError(f"{what} {str(p)!r}: file not found")
    if not p.is_file():
        raise AgentError(f"{what} {str(p)!r}: not a regular file")
    return p


def shipped_agent_dir(target: str) -> pathlib.Path | None:
    """The shipped agent folder that ``target`` names, or None.

    Only a bare name (no ``/``) that is not also a file or folder in the working directory names a shipped
    agent: a local path always wins, so shipping an agent never changes what an existing spec loads.
    """
    if "/" in target or target in LOCAL_COPIES or pathlib.Path(target).expanduser().exists():
        return None
    folder = ASSETS_DIR / target
    return folder if folder.is_dir() else None


def shipped_agent_names(holding: str = "*") -> list[str]:
    """Names of the agents shipped in :data:`ASSETS_DIR` whose folder holds a file matching the glob ``holding``.

    Kinds pass their own file pattern (``"*.tar"`` for dcd) so that an error lists only agents of that kind.
    """
    if not ASSETS_DIR.is_dir():
        return []
    return sorted(p.name for p in ASSETS_DIR.iterdir() if p.is_dir() and any(p.glob(holding)))


def verified_files(folder: pathlib.Path, *, what: str) -> list[pathlib.Path]:
    """The files ``folder/SHA256SUMS`` lists, each checked against its recorded sha256.

    Args:
        folder: A folder holding :data:`CHECKSUMS_FILE`.
        what: What the folder is, for error messages (e.g. ``"shipped agent 'accel'"``).

    Raises:
        AgentError: No checksum file, a malformed line, a listed file missing, or a file whose sha256 differs
            from the recorded one (a corrupt or modified install).
    """
    checksums = folder / CHECKSUMS_FILE
    try:
        lines = checksums.read_text().splitlines()
    except OSError as exc:
        raise AgentError(f"{what}: cannot read {str(checksums)!r} ({describe_exception(exc)})") from None
    files = []
    for line in filter(str.strip, lines):
        expected, _, name = line.partition("  ")
        if len(expected) != 64 or not name:
            raise AgentError(f"{what}: {str(checksums)!r} line {line!r} is not '<sha256>  <file>'")
        path = folder / name.lstrip("*")  # sha256sum marks binary-mode entries with '*'
        try:
            actual = hashlib.sha256(path.read_bytes()).hexdigest()
        except OSError as exc:
            raise AgentError(f"{what}: cannot read {str(path)!r} ({describe_exception(exc)})") from None
        if actual != expected.lower():
            raise AgentError(f"{what}: {str(path)!r} is corrupt: sha256 {actual} does not match the recorded "
                             f"{expected} (reinstall dsage-ray)")
        files.append(path)
    if not files:
        raise AgentError(f"{what}: {str(checksums)!r} lists no files")
    return files


def describe_exception(exc: BaseException, *, limit: int = 160) -> str:
    """``"Type: first line of the message"``, shortened: enough to say what went wrong in one line.

    A ``torch.load(weights_only=True)`` refusal is named by what it refused, without torch's advice to retry with
    ``weights_only=False`` (which would run the file's code: the point of refusing).
    """
    refused = re.search(r"unsupported (GLOBAL [\w.]+|[\w ]+ \w+)", str(exc))
    if str(exc).startswith("Weights only load failed") and refused:
        return (f"it holds more than tensors ({refused.group(1)}), and such a file is read as data only; "
                f"nothing in it ran")
    lines = str(exc).strip().splitlines()
    line = lines[0] if lines else ""
    line = line if len(line) <= limit else line[: limit - 3] + "..."
    return f"{type(exc).__name__}: {line}" if line else type(exc).__name__
