"""Agents as data on a Ray cluster: the files an agent spec names travel with the work, not through a shared path.

The process that starts the work (the driver of an audit or run, or a Tune trial) reads the file or folder each agent
spec of the config names (``dcd:PATH``, ``rllib:PATH``, ``torchscript:PATH``, ``sb3:PATH``,
``python:FILE.py:FUNCTION``) into bytes once, :func:`pack_agent_files`, and hands them to Ray (the simulator actors'
arguments, or ``tune.with_parameters``), which moves them through its object store to whichever node runs the
work. There, :func:`install_agent_files` unpacks them into a private temporary folder and records where, so that
the loaders, which open every path through :func:`local_path`, read the unpacked copy: no node but the driver's
needs the path, and the file may even be gone from the driver's disk once the work has started.

Not shipped: agents shipped in the package (``rllib:ppo_maze``, ``dcd:accel``: every node has the package),
``python:MODULE:FUNCTION`` (an installed module, like any dependency) and the kinds of plug-ins (the plug-in
package decides what its spec means; install it on every node).
"""

from __future__ import annotations

import dataclasses
import io
import pathlib
import tarfile
import tempfile
from typing import Any, Iterable, Mapping

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.loader import LOCAL_COPIES, local_path, parse_spec, shipped_agent_dir

#: Kinds whose target is a file or folder path (``python``: when it names a ``.py`` file).
FILE_KINDS = ("dcd", "rllib", "torchscript", "sb3", "qtable", "python")
#: Name of the unpacked file or folder inside its temporary folder.
_MEMBER = "agent"


@dataclasses.dataclass(frozen=True)
class AgentFiles:
    """The bytes of one path an agent spec names.

    Attributes:
        target: The path exactly as the spec names it (relative paths stay relative: the key is the text).
        archive: An uncompressed tar of the file or folder, under the name ``agent``.
    """

    target: str
    archive: bytes


def spec_paths(spec: str) -> list[str]:
    """The paths on disk that ``spec`` names (empty for a shipped agent, a module, or a kind without files)."""
    try:
        kind, target, _ = parse_spec(spec)
    except AgentError:
        return []  # "astar", "random": no target
    if kind not in FILE_KINDS:
        return []
    if kind == "python":
        location = target.rpartition(":")[0]
        return [location] if location.endswith(".py") else []
    return [] if shipped_agent_dir(target) is not None else [target]


def config_agent_specs(values: Mapping[str, Any]) -> list[str]:
    """The agent specs among a config's values that name files (``maze.agent``, ``maze.reference``, ``gym.agent``),
    in a nested section, a flat Tune config, or the value lists of its ``tune.grid_search`` axes."""
    found: list[str] = []
    for value in values.values():
        if isinstance(value, Mapping):
            found += config_agent_specs(value if "grid_search" not in value else dict(enumerate(value["grid_search"])))
        elif isinstance(value, str) and spec_paths(value):
            found.append(value)
    return found


def pack_agent_files(specs: Iterable[str]) -> tuple[AgentFiles, ...]:
    """Reads every path ``specs`` name into bytes (each once); a path that does not exist is left to the loader,
    which names it.

    Raises:
        AgentError: A path that exists but cannot be read.
    """
    packed: dict[str, AgentFiles] = {}
    for spec in specs:
        for target in spec_paths(spec):
            path = pathlib.Path(local_path(target)).expanduser()
            if target in packed or not path.exists():
                continue
            buffer = io.BytesIO()
            try:
                with tarfile.open(fileobj=buffer, mode="w") as archive:
                    archive.add(path, arcname=_MEMBER)
            except OSError as exc:
                raise AgentError(f"agent {spec!r}: cannot read {str(path)!r} ({exc.strerror or exc})") from None
            packed[target] = AgentFiles(target=target, archive=buffer.getvalue())
    return tuple(packed.values())


def install_agent_files(files: Iterable[AgentFiles]) -> None:
    """Unpacks each of ``files`` into a private temporary folder of this process and makes :func:`local_path` of
    its target point there (a target already installed here is left as it is)."""
    for item in files:
        if item.target in LOCAL_COPIES:
            continue
        folder = pathlib.Path(tempfile.mkdtemp(prefix="dsage_ray_agent_"))
        with tarfile.open(fileobj=io.BytesIO(item.archive), mode="r") as archive:
            archive.extractall(folder, filter="data")  # names and links stay inside the folder
        LOCAL_COPIES[item.target] = str(folder / _MEMBER)
