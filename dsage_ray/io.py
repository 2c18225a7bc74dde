"""Atomic file writes (a crash never leaves a half-written output or checkpoint behind) and the lock that keeps two
writers out of one output folder."""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import functools
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterator

from dsage_ray.errors import InputError

#: The lock file :func:`folder_lock` holds in an output folder.
LOCK_NAME = ".dsage_ray.lock"


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Writes ``data`` to a temporary file beside ``path``, fsyncs it, then renames it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        # mkstemp creates 0600 files; outputs get the permissions a plain open() would give them.
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: Read once at import: reading the umask means setting it, which is not thread-safe.
_UMASK = _read_umask()


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2, default=_json_default) + "\n")


def staging_dir(final: str | Path) -> Path:
    """A fresh empty folder beside ``final`` to write into before :func:`replace_dir` swaps it in.

    Its name is unique (concurrent writers never share one) and its permissions are those of a
    plain ``mkdir`` (``mkdtemp`` alone makes it private).
    """
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".staging", dir=final.parent))
    os.chmod(staging, 0o777 & ~_UMASK)
    return staging


def replace_dir(staging: Path, final: Path) -> None:
    """Swaps a fully written ``staging`` folder in for ``final`` (old contents removed last).

    Where the system can exchange two paths in one step (Linux), ``final`` is never missing; elsewhere it is
    missing between two renames, and :func:`recover_replaced_dir` puts the old contents back if a writer died there.
    """
    final = Path(final)
    if final.exists() and _exchange(staging, final):
        shutil.rmtree(staging)  # now holds the old contents
        return
    old = final.with_name(f".{final.name}.old")
    if old.exists():
        shutil.rmtree(old)
    if final.exists():
        os.replace(final, old)
    os.replace(staging, final)
    if old.exists():
        shutil.rmtree(old)


def recover_replaced_dir(final: str | Path) -> None:
    """Clears what a writer of ``final`` killed mid-way left beside it: its staging folders are removed, and old
    contents it had moved aside are put back if ``final`` itself is missing.

    Call it only while holding the :func:`folder_lock` its writers take (a live writer's staging folder would go).
    """
    final = Path(final)
    for stale in final.parent.glob(f".{final.name}.*.staging"):
        shutil.rmtree(stale, ignore_errors=True)
    old = final.with_name(f".{final.name}.old")
    if old.is_dir():
        if final.exists():
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(old, final)


@contextlib.contextmanager
def folder_lock(folder: str | Path, *, what: str) -> Iterator[Path]:
    """Holds ``folder`` for one writer: a second run or audit on the same folder stops with one line.

    The lock is an advisory ``flock`` on ``folder/.dsage_ray.lock``, so it ends with the process however it ends
    (a crash or a kill leaves no stale lock). Taking it also creates ``folder``: an output folder that cannot be
    written fails here, before any work. A folder it created is removed again if nothing was written into it.

    Args:
        folder: The output folder (created if missing).
        what: What writes it (``"audit"``, ``"run"``), for the message.

    Raises:
        InputError: ``folder`` cannot be created or written, or another process holds it.
    """
    folder = Path(folder)
    created = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle = os.open(folder / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o666 & ~_UMASK)
    except OSError as exc:
        raise InputError(f"{folder}: cannot write the {what}'s output there ({exc.strerror or exc})") from None
    try:
        _lock(handle, folder=folder, what=what)
        os.ftruncate(handle, 0)
        os.write(handle, f"{os.getpid()}\n".encode())
        yield folder
    finally:
        if created and [path.name for path in folder.iterdir()] == [LOCK_NAME]:
            # Stopped before writing anything (bad input found after the lock): leave no folder behind.
            (folder / LOCK_NAME).unlink()
            folder.rmdir()
        os.close(handle)  # closing releases the lock


def _lock(handle: int, *, folder: Path, what: str) -> None:
    try:
        import fcntl
    except ImportError:  # Windows: no flock; one writer per folder is then the user's to keep
        return
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(handle, 32, 0).decode(errors="replace").strip() or "unknown"
        raise InputError(f"{folder}: another {what} is writing this folder (process {holder}); wait for it to "
                         f"end, or choose another --out") from None


def _exchange(first: Path, second: Path) -> bool:
    """Swaps two paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); False where the system cannot."""
    renameat2 = _renameat2()
    if renameat2 is None:
        return False
    at_cwd, rename_exchange = -100, 2
    if renameat2(at_cwd, os.fsencode(first), at_cwd, os.fsencode(second), rename_exchange) == 0:
        return True
    if ctypes.get_errno() in (errno.EINVAL, errno.ENOSYS, errno.EPERM):  # a filesystem or kernel without it
        return False
    raise OSError(ctypes.get_errno(), os.strerror(ctypes.get_errno()), str(second))


@functools.cache
def _renameat2() -> Any:
    name = ctypes.util.find_library("c")
    function = getattr(ctypes.CDLL(name, use_errno=True), "renameat2", None) if name else None
    if function is not None:
        function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    return function


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__} to JSON")
