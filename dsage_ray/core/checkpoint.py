"""The one checkpoint format: a run's full state in one file, written atomically, checked on load.

``--local`` runs, Tune trials (one file inside each of Tune's checkpoint folders), the audit and pretrained
surrogates all read and write this format through :func:`save_checkpoint` / :func:`load_checkpoint`.

A file is three parts::

    dsage_ray checkpoint\\n      magic line: a foreign file is recognised before anything is read
    {"format": 3, ...}\\n         JSON header: format version, library versions, payload size and sha256
    <data pickle>                the state (:mod:`~dsage_ray.safe_pickle`)

**Opening a checkpoint runs no code.** The state holds pyribs archives and emitters with their internal
``numpy.random.Generator`` states, which pickle exactly and nothing else stores, so the payload is a pickle, read
by :mod:`~dsage_ray.safe_pickle`: only an allowlist of data classes is resolved, torch tensors are stored as
raw bytes, and a pickle naming anything else is refused before it is called. A checkpoint can be shared like any
data file. :func:`save_checkpoint` reads back what it wrote, so a state this reader would refuse fails when it is
saved, not when a run resumes.

Pickles restore objects by their classes' private layout, so the header records the versions of the libraries
whose objects the state holds and :func:`load_checkpoint` compares them with the running ones:

* **pyribs**: its private attribute layout changes between minor releases, and an archive from
  another release would restore silently wrong; a different ``major.minor`` is an error
  (:class:`CheckpointVersionError`), a different patch release a warning.
* **numpy**, **torch**, **dsage_ray**: their pickles load across versions (numpy 2 reads numpy 1
  pickles; tensors are raw bytes and the runner's plain-dict state is stable), but a continued run may
  not reproduce the interrupted one bit for bit, so a difference is a warning
  (:class:`CheckpointVersionWarning`). A load that fails outright still names the file.

The sha256 in the header catches a damaged file (a flipped bit would otherwise load as a subtly wrong state); it
is no signature: anyone can recompute it, which is why the reader relies on the allowlist, not on it.
"""

from __future__ import annotations

import functools
import hashlib
import json
import warnings
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from dsage_ray import safe_pickle
from dsage_ray.errors import InputError
from dsage_ray.io import atomic_write_bytes

if TYPE_CHECKING:
    from dsage_ray.config import RunConfig

#: File name of a checkpoint: in a ``--local`` run folder, and inside each Tune checkpoint folder.
CHECKPOINT_NAME = "checkpoint.dsage"
#: Version of the file layout above; a reader refuses other versions.
FORMAT_VERSION = 3
_MAGIC = b"dsage_ray checkpoint\n"
#: Distribution names of the libraries whose versions the header records (pyribs is ``ribs``).
_LIBRARIES = ("dsage_ray", "ribs", "numpy", "torch")
#: The header is one short JSON line; a longer "header" means a foreign file that happens to match the magic.
_MAX_HEADER_BYTES = 64 * 1024


class CheckpointError(InputError):
    """A file that is not a dsage_ray checkpoint, or a damaged one; the message names the file."""


class CheckpointVersionError(CheckpointError):
    """A checkpoint written with a library version whose objects this one cannot restore faithfully."""


class CheckpointVersionWarning(UserWarning):
    """A checkpoint written with other library versions that still load (results may differ in the last bit)."""


def library_versions() -> dict[str, str]:
    """Versions of the libraries a checkpoint's objects come from, read without importing them."""
    return dict(_installed_versions())


@functools.cache  # installed versions do not change while a process runs; reading them scans sys.path
def _installed_versions() -> tuple[tuple[str, str], ...]:
    versions = {}
    for name in _LIBRARIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:  # a source checkout run without installing it
            versions[name] = "unknown"
    return tuple(versions.items())


def save_checkpoint(state: Mapping[str, Any], path: str | Path) -> Path:
    """Writes ``state`` to ``path`` atomically (a crash never leaves a truncated checkpoint).

    Pickle everything that shares objects in **one** call, as this does: a scheduler and its
    archive pickled separately would restore as two different archives.

    Args:
        state: A picklable state, e.g. :meth:`dsage_ray.core.runner.DSAGE.state_dict`.
        path: The file to write; its folder is created if needed.

    Returns:
        ``path``.
    """
    payload = safe_pickle.dumps(dict(state))
    try:
        safe_pickle.loads(payload)
    except safe_pickle.UnsafePickleError as exc:  # a bug of dsage_ray's, not of the user's: name what to allow
        raise TypeError(f"cannot save a checkpoint to {path}: {exc}") from None
    header = {
        "format": FORMAT_VERSION,
        "libraries": library_versions(),
        "payload_bytes": len(payload),
        "payload_sha256": hashlib.sha256(payload).hexdigest(),
    }
    if isinstance(state.get("config"), Mapping):
        header["config"] = state["config"]  # read_header gives a run's config without unpickling its state
    path = Path(path)
    atomic_write_bytes(path, _MAGIC + json.dumps(header, sort_keys=True).encode() + b"\n" + payload)
    return path


def read_header(path: str | Path) -> dict[str, Any]:
    """The header of the checkpoint at ``path`` (format, library versions, payload size, and the run's config
    where the state had one), unpickling nothing.

    Raises:
        CheckpointError: No such file, or not a dsage_ray checkpoint of a format this version reads.
    """
    path = Path(path)
    header, _ = _split(path, _read(path, limit=len(_MAGIC) + _MAX_HEADER_BYTES))
    return header


def latest_tune_checkpoint(folder: Path, trials: str) -> Path | None:
    """The checkpoint file in the highest-numbered ``checkpoint_NNNNNN`` folder of the Tune trials ``trials`` (a
    glob under ``folder``, e.g. ``"*"`` for an experiment's trials); None when there is none."""
    found = sorted(folder.glob(f"{trials}/checkpoint_*/{CHECKPOINT_NAME}"),
                   key=lambda path: int(path.parent.name.rsplit("_", 1)[-1]))
    return found[-1] if found else None


def checkpoint_config(path: str | Path) -> "RunConfig":
    """The config of the run that wrote the checkpoint at ``path``, read from its header (unpickling nothing).

    Raises:
        CheckpointError: As :func:`read_header`, or a config this version cannot read (the message says why).
    """
    from dsage_ray.config import ConfigError, RunConfig

    stored = read_header(path).get("config")
    if not isinstance(stored, dict):
        raise CheckpointError(f"{path}: holds no run config (not a checkpoint dsage_ray wrote, or a damaged one)")
    try:
        return RunConfig.build(stored)
    except ConfigError as exc:
        raise CheckpointError(f"{path}: the run's config does not load here ({exc})") from None


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """Reads the state :func:`save_checkpoint` wrote, after checking the file and the library versions.

    Raises:
        CheckpointError: No such file, a foreign or damaged file, or a state that does not unpickle.
        CheckpointVersionError: Written with another pyribs ``major.minor`` (module docstring).

    Warns:
        CheckpointVersionWarning: Written with other numpy, torch, dsage_ray or pyribs patch versions.
    """
    path = Path(path)
    header, payload = _split(path, _read(path))
    if len(payload) != header.get("payload_bytes") or hashlib.sha256(payload).hexdigest() != header.get(
            "payload_sha256"):
        raise CheckpointError(f"{path}: damaged checkpoint (its contents do not match the checksum in its header)")
    check_library_versions(header.get("libraries", {}), path=path)
    try:
        state = safe_pickle.loads(payload)
    except safe_pickle.UnsafePickleError as exc:
        raise CheckpointError(f"{path}: refused: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - unpickling can raise almost anything; the versions are in the header.
        raise CheckpointError(f"{path}: the checkpoint's state does not load ({type(exc).__name__}: {exc}); it was "
                              f"written with {_format_versions(header.get('libraries', {}))}") from None
    if not isinstance(state, dict):
        raise CheckpointError(f"{path}: the checkpoint holds a {type(state).__name__}, not a run state")
    return state


def check_library_versions(saved: Mapping[str, str], *, path: str | Path) -> None:
    """Compares a checkpoint's library versions with the running ones (module docstring for the rules).

    Raises:
        CheckpointVersionError: Another pyribs ``major.minor``.

    Warns:
        CheckpointVersionWarning: Any other difference.
    """
    running = library_versions()
    differing = {name: (saved[name], running[name]) for name in _LIBRARIES
                 if name in saved and saved[name] != running[name]}
    if "ribs" in differing:
        then, now = differing["ribs"]
        if _minor(then) != _minor(now):
            raise CheckpointVersionError(
                f"{path}: checkpoint written with pyribs {then}, this is pyribs {now}; pyribs archives do not "
                f"restore faithfully across minor releases (install ribs=={then} to continue this run)")
    if differing:
        listed = ", ".join(f"{name} {then} (now {now})" for name, (then, now) in sorted(differing.items()))
        warnings.warn(f"{path}: checkpoint written with {listed}; it loads, but a continued run may not match "
                      f"an uninterrupted one bit for bit", CheckpointVersionWarning, stacklevel=3)


def _read(path: Path, limit: int = -1) -> bytes:
    try:
        with path.open("rb") as handle:
            return handle.read(limit)
    except FileNotFoundError:
        raise CheckpointError(f"{path}: no such checkpoint") from None
    except IsADirectoryError:
        raise CheckpointError(f"{path}: is a folder, not a checkpoint file") from None
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot read the checkpoint ({exc.strerror or exc})") from None


def _split(path: Path, data: bytes) -> tuple[dict[str, Any], bytes]:
    """``(header, payload)`` of a checkpoint's bytes (the payload may be cut short when only the header was read)."""
    if not data.startswith(_MAGIC):
        raise CheckpointError(f"{path}: not a dsage_ray checkpoint (it does not start with {_MAGIC.strip()!r})")
    end = data.find(b"\n", len(_MAGIC))
    if end < 0:
        raise CheckpointError(f"{path}: damaged checkpoint (its header is incomplete)")
    try:
        header = json.loads(data[len(_MAGIC):end])
    except (UnicodeDecodeError, json.JSONDecodeError):
        header = None
    if not isinstance(header, dict) or not isinstance(header.get("format"), int):
        raise CheckpointError(f"{path}: damaged checkpoint (its header is not the JSON object it should be)")
    if header["format"] == FORMAT_VERSION:
        return header, data[end + 1:]
    raise CheckpointError(f"{path}: checkpoint format {header['format']}, this dsage_ray reads format "
                          f"{FORMAT_VERSION} (written by dsage_ray {header.get('libraries', {}).get('dsage_ray')})")


def _minor(version: str) -> tuple[str, ...]:
    return tuple(version.split(".")[:2])


def _format_versions(versions: Mapping[str, str]) -> str:
    return ", ".join(f"{name} {version}" for name, version in sorted(versions.items())) or "unknown versions"
