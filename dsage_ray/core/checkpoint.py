"""Saving and restoring a run's full state as one file, atomically."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

from dsage_ray.errors import InputError
from dsage_ray.io import atomic_write_bytes

CHECKPOINT_NAME = "checkpoint.pkl"
_FORMAT = "dsage_ray.checkpoint.v1"


class CheckpointError(InputError):
    """A file that is not a dsage_ray checkpoint, or a damaged one."""


def save_checkpoint(state: dict[str, Any], path: str | Path) -> None:
    atomic_write_bytes(path, pickle.dumps({"format": _FORMAT, "state": state}, protocol=pickle.HIGHEST_PROTOCOL))


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    try:
        payload = pickle.loads(path.read_bytes())
    except FileNotFoundError:
        raise CheckpointError(f"{path}: no such checkpoint") from None
    except Exception as exc:  # noqa: BLE001 - unpickling garbage can raise almost anything.
        raise CheckpointError(f"{path}: not a readable dsage_ray checkpoint ({type(exc).__name__}: {exc})") from None
    if not isinstance(payload, dict) or payload.get("format") != _FORMAT:
        raise CheckpointError(f"{path}: not a dsage_ray checkpoint (expected format {_FORMAT})")
    return payload["state"]
