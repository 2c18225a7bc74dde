"""Fixtures for agent tests: one torch thread, and where the optional original files live."""

from __future__ import annotations

import os
import pathlib

import pytest
import torch

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]


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
