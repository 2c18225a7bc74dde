"""A Tune run's storage as a URI: locations, and trials on a remote filesystem read from a local copy.

A run stored at a file URI, read back and resumed by the same URI, is
``tests/ray/test_ray_progress.py``'s Tune run (a Tune start costs more than the run).
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pyarrow.fs

import dsage_ray
from dsage_ray.core.checkpoint import CHECKPOINT_NAME
from dsage_ray.ray import storage
from dsage_ray.ray.experiment import _run_result

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "experiments" / "configs" / "maze_dsage.toml"


def test_locations_paths_and_uris():
    assert storage.local_folder("file:///srv/runs") == Path("/srv/runs")
    assert storage.local_folder("tb_logs") == Path("tb_logs")
    assert storage.local_folder("s3://bucket/runs") is None
    assert storage.storage_location("s3://bucket/runs") == "s3://bucket/runs"
    assert Path(storage.storage_location("tb_logs")).is_absolute()


def test_a_trial_on_a_remote_filesystem_is_read_from_a_local_copy(tmp_path):
    # A filesystem that is not this machine's (pyarrow reads it like a bucket): the driver gets copies.
    trial = tmp_path / "bucket" / "exp" / "trial_0"
    (trial / "checkpoint_000001").mkdir(parents=True)
    (trial / "checkpoint_000001" / CHECKPOINT_NAME).write_bytes(b"state")
    (trial / "metrics.json").write_text(json.dumps([{"evals": 60}]))
    remote = pyarrow.fs.SubTreeFileSystem(str(tmp_path / "bucket"), pyarrow.fs.LocalFileSystem())
    checkpoint = SimpleNamespace(path="exp/trial_0/checkpoint_000001", filesystem=remote)
    result = _run_result(dsage_ray.resolve_config(CONFIG, preset="tiny").to_flat(), "exp/trial_0", checkpoint)
    assert not result.path.is_relative_to(tmp_path) and result.metrics == [{"evals": 60}]
    assert result.checkpoint.read_bytes() == b"state"
