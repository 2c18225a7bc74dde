"""Fixtures for agent tests: small checkpoints written on the fly, and the real ACCEL checkpoint when present."""

from __future__ import annotations

import os
import pathlib

import pytest
import torch

from dsage_ray.agents.dcd import DCDNetwork

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]


def shared_dir() -> pathlib.Path:
    """``$DSAGE_SHARED_DIR``, else ``../shared`` next to the repository root."""
    return pathlib.Path(os.environ.get("DSAGE_SHARED_DIR", REPO_ROOT.parent / "shared"))


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread():
    """Small batched steps on a small shared CPU: 2 intra-op threads cost ~10x more than 1. Restored after."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="session")
def accel_checkpoint() -> pathlib.Path:
    """The real ACCEL checkpoint, read in place (never copied into the repo); skips when it is absent."""
    path = shared_dir() / "models" / "accel_seed_1" / "model_20000.tar"
    if not path.is_file():
        pytest.skip(f"ACCEL checkpoint not found at {path} (set DSAGE_SHARED_DIR to the shared folder)")
    return path


@pytest.fixture
def random_dcd_checkpoint(tmp_path) -> pathlib.Path:
    """A DCD-format state_dict with random weights: the real file's format without needing the real file."""
    torch.manual_seed(0)
    path = tmp_path / "model.tar"
    torch.save(DCDNetwork().state_dict(), path)
    return path
