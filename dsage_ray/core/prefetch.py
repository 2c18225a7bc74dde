"""``pipeline = true``: DSAGE's next proposal made while this iteration's picks are evaluated.

Training, exploitation and selection for iteration k+1 run while iteration k's picks are evaluated, so the
surrogate that picks them has trained on the evaluations up to iteration k−1 only. With simulators in other
processes (an evaluator with ``runs_elsewhere``, such as the Ray pool) the batch is submitted first and the driver
trains and exploits while it runs; in one process the two run one after the other. The data each phase sees is the
same either way, so a seed gives the same run in both, and a checkpoint holds the next iteration's picks
(``pending_proposal``). The first iteration cannot overlap: nothing is known until its random batch is back, so its
next proposal is made once it is learned. An iteration's ``time_*`` entries are the phases that ran during it, so a
pipelined iteration's ``time_train`` is the next picks' training; ``time_overlapped`` is how long the driver worked
while the batch was being evaluated.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

from dsage_ray.core.proposal import EvaluatedBatch, Proposal, Proposer, ProposerWrapper, Simulation


class Prefetching(ProposerWrapper):
    """Proposes iteration k+1 while iteration k's batch is evaluated (``pipeline = true``).

    Args:
        inner: The proposer whose proposals are made early (DSAGE's
            :class:`~dsage_ray.core.proposers.SurrogateAssisted`).

    Attributes:
        pending: The next iteration's proposal, made already (None: none yet).
    """

    def __init__(self, *, inner: Proposer) -> None:
        self.inner = inner
        self.pending: Proposal | None = None
        self._outer_iteration = 0
        self._simulation: Simulation | None = None

    def propose(self, *, outer_iteration: int) -> Proposal:
        self._outer_iteration = outer_iteration
        if self.pending is None:
            return self.inner.propose(outer_iteration=outer_iteration)
        proposal, self.pending = self.pending, None
        # Its phases ran, and were counted, in the iteration that made it.
        return dataclasses.replace(proposal, times={})

    def evaluate(self, simulation: Simulation) -> None:
        self._simulation = simulation
        running = simulation.start()
        if self._outer_iteration > 0 and simulation.evals + simulation.count < simulation.budget:
            tic = time.perf_counter()
            self._prefetch(simulation)
            if running.overlapped:
                simulation.times["overlapped"] = time.perf_counter() - tic
        running.result()

    def learn(self, batch: EvaluatedBatch) -> dict[str, float]:
        metrics = self.inner.learn(batch)
        simulation = self._simulation
        # None was made while the batch was out (the first iteration): the next is made now, unless a budget is spent.
        time_left = simulation.time_left()
        if (self.pending is None and simulation.evals + len(batch.solutions) < simulation.budget
                and (time_left is None or time_left > 0)):
            self._prefetch(simulation)
        return metrics

    def _prefetch(self, simulation: Simulation) -> None:
        """The next iteration's proposal, made now; its phases' seconds count in this iteration's."""
        self.pending = self.inner.propose(outer_iteration=self._outer_iteration + 1)
        simulation.add_times(self.pending.times)

    def state_dict(self) -> dict[str, Any]:
        return {**self.inner.state_dict(),
                "pending_proposal": None if self.pending is None else self.pending.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.inner.load_state_dict(state)
        pending = state.get("pending_proposal")
        self.pending = None if pending is None else Proposal.from_state_dict(pending)
