"""Fixtures for the Maze's agent tests: small checkpoints written on the fly, the shipped ACCEL checkpoint, and
:func:`load_error` (a spec's one-line error)."""

from __future__ import annotations

import pathlib

import pytest
import torch

from dsage_ray.agents import AgentError
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.dcd import DCDNetwork, resolve_dcd_checkpoint
from tests.agents.conftest import REPO_ROOT, one_torch_thread, shared_dir  # noqa: F401 - fixtures, and helpers

#: The ACCEL agent shipped with the package; the tests need nothing outside the repository.
ACCEL_SPEC = "dcd:accel"


def load_error(spec: str) -> AgentError:
    """The error loading ``spec`` as a Maze agent raises: one line, no torch traceback chained to it."""
    with pytest.raises(AgentError) as info:
        load_maze_agent(spec)
    err = info.value
    assert "\n" not in str(err), f"multi-line error: {err}"
    assert err.__cause__ is None and err.__suppress_context__ or err.__context__ is None, "torch traceback leaked"
    return err


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
