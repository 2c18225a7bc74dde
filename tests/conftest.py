"""Suite-wide test settings."""

import os

import pytest
import torch

os.environ.setdefault("RAY_AUTH_MODE", "disabled")


@pytest.fixture(autouse=True, scope="session")
def one_torch_thread():
    """One intra-op thread per test process: CI has 2 cores and Ray workers share them.

    With 2 threads on a busy 2-core machine torch's threads wait on each other at every op and
    small models run 3–4× slower.
    """
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)
