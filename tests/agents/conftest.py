"""Fixtures for agent tests: small checkpoints written on the fly, and the shipped ACCEL checkpoint."""

from __future__ import annotations

import os
import pathlib

import pytest
import torch

from dsage_ray.agents.dcd import DCDNetwork, resolve_dcd_checkpoint

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
#: The ACCEL agent shipped with the package; the tests need nothing outside the repository.
ACCEL_SPEC = "dcd:accel"


def shared_dir() -> pathlib.Path:
    """``$DSAGE_SHARED_DIR``, else ``../shared`` next to the repository root (optional: the original files)."""
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
    """The shipped ACCEL checkpoint file, sha256-verified (what ``dcd:accel`` loads)."""
    return resolve_dcd_checkpoint("accel")


@pytest.fixture
def random_dcd_checkpoint(tmp_path) -> pathlib.Path:
    """A DCD-format state_dict with random weights: the real file's format without needing the real file."""
    torch.manual_seed(0)
    path = tmp_path / "model.tar"
    torch.save(DCDNetwork().state_dict(), path)
    return path
