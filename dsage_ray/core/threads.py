"""Torch's intra-op thread count, pinned for a block of work."""

from __future__ import annotations

import contextlib
from typing import Iterator


@contextlib.contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Runs the block with ``count`` torch intra-op threads, then restores the caller's count.

    The count a run trains and predicts with is part of its config, so ``--local``, a Tune trial
    and a resumed run compute the same floats whatever their process was set to.
    """
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
