"""The seed streams of one run, all derived from the run seed.

Each consumer has a stream of its own, so that, e.g., a different inner-loop length never shifts
the evaluation seeds, and holding levels out never changes what the search finds.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def _indexed_seed(root: int, index: int) -> int:
    return int(np.random.SeedSequence([root, index]).generate_state(1)[0])


class RunSeeds:
    """Every random number a run draws comes from here.

    Args:
        seed: The run seed (``config.seed``).

    Attributes:
        rng: The search's generator: random levels of the first iteration, the selection's draws.
        holdout_levels: Seeds the held-out levels (a ``SeedSequence``; spawned after the other streams,
            which therefore do not depend on whether levels are held out).
    """

    def __init__(self, *, seed: int) -> None:
        root = np.random.SeedSequence(seed)
        search, evaluations, qd = root.spawn(3)
        self.rng = np.random.default_rng(search)
        self._evaluation_root = int(evaluations.generate_state(1)[0])
        self._qd_root = qd
        self.holdout_levels, holdout_evaluations = root.spawn(1)[0].spawn(2)
        self._holdout_evaluation_root = int(holdout_evaluations.generate_state(1)[0])

    def evaluation(self, index: int) -> int:
        """Evaluation ``index``'s seed: a function of the run seed and ``index`` alone, never of who evaluates it."""
        return _indexed_seed(self._evaluation_root, index)

    def holdout_evaluation(self, index: int) -> int:
        """The seed of held-out level ``index``'s evaluation."""
        return _indexed_seed(self._holdout_evaluation_root, index)

    def next_qd_seed(self) -> int:
        """A fresh seed for the next archive, scheduler or surrogate initialisation, in order of creation."""
        return int(self._qd_root.spawn(1)[0].generate_state(1)[0])

    def first_qd_seeds(self) -> tuple[int, int]:
        """The QD stream's first two seeds, as :meth:`next_qd_seed` gives them at a run's start (the stream is not
        advanced): the run's archive's and its first search's (a direct run's scheduler). A direct search that takes
        over a run later (``search = "auto"``) draws these, so that it asks what a run of it from the start would."""
        root = self._qd_root
        return tuple(int(np.random.SeedSequence(root.entropy, spawn_key=(*root.spawn_key, index),
                                                pool_size=root.pool_size).generate_state(1)[0]) for index in (0, 1))

    def state_dict(self) -> dict[str, Any]:
        """The streams that advance during a run (the others are fixed by the run seed)."""
        return {"rng": self.rng.bit_generator.state, "qd_seed_root": self._qd_root}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.rng.bit_generator.state = state["rng"]
        self._qd_root = state["qd_seed_root"]
