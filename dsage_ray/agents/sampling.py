"""Categorical sampling shared by the neural agents.

Sampling happens in numpy from the caller's ``rng`` rather than through ``torch.distributions``: it keeps
evaluations reproducible from one seed, and it avoids the distribution object's per-call overhead, which
dominates at the small batch sizes of an evaluation (SPEC: speed).
"""

from __future__ import annotations

import numpy as np
import torch


def sample_from_logits(logits: torch.Tensor, rng: np.random.Generator) -> np.ndarray:
    """Draws one action per row of ``logits`` by inverse-CDF sampling with ``rng.random(n)``.

    Args:
        logits: Unnormalised log-probabilities, shape ``(n, num_actions)``.
        rng: The only source of randomness; exactly ``n`` uniforms are drawn from it.

    Returns:
        Actions, shape ``(n,)``, int64.
    """
    probs = torch.softmax(logits.double(), dim=-1).numpy()
    cdf = np.cumsum(probs, axis=1)
    # Scale the uniforms by the row total so rounding in the cumulative sum cannot push u past the end.
    u = rng.random(len(cdf)) * cdf[:, -1]
    actions = (cdf <= u[:, None]).sum(axis=1)
    return np.minimum(actions, cdf.shape[1] - 1).astype(np.int64)
