"""Where Tune keeps an experiment's trials: a folder, or a URI of a filesystem Tune writes through pyarrow
(``file:///shared/runs``, ``s3://bucket/runs``, ``gs://bucket/runs``).

``dsage-ray run --out`` / ``ablate --out`` / ``experiments/ablation.py --storage`` take either. The driver reads a
finished trial back through the same storage layer Tune wrote it with (the trial's ``pyarrow`` filesystem): a
trial on a local filesystem is read in place, one on a remote filesystem is copied into a local cache first
(:func:`local_copy`), so a cluster needs no shared folder for its results either.
"""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path
from typing import Any
from urllib.parse import urlparse


def is_uri(location: str | Path) -> bool:
    """Whether ``location`` is a URI (``scheme://...``) rather than a path."""
    return "://" in str(location)


def storage_location(location: str | Path) -> str:
    """What Tune's ``storage_path`` gets: a URI as given, a path made absolute (Tune needs one)."""
    return str(location) if is_uri(location) else str(Path(location).expanduser().resolve())


def local_folder(location: str | Path) -> Path | None:
    """The folder on this machine that ``location`` is (a path, or a ``file://`` URI); None for a remote URI."""
    if not is_uri(location):
        return Path(location).expanduser()
    parsed = urlparse(str(location))
    return Path(parsed.path) if parsed.scheme == "file" else None


def local_copy(path: str, filesystem: Any) -> Path:
    """``path`` on ``filesystem`` (a trial or checkpoint folder, as Tune reports it) as a folder on this machine: the
    folder itself on a local filesystem, else a copy in this machine's temporary folder (refreshed on each call)."""
    import pyarrow.fs

    if filesystem is None or isinstance(filesystem, pyarrow.fs.LocalFileSystem):
        return Path(path)
    cache = Path(tempfile.gettempdir()) / "dsage_ray_results" / hashlib.sha256(path.encode()).hexdigest()[:16]
    cache.mkdir(parents=True, exist_ok=True)
    pyarrow.fs.copy_files(path, str(cache), source_filesystem=filesystem,
                          destination_filesystem=pyarrow.fs.LocalFileSystem())
    return cache
