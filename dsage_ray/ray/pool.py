"""A pool of Ray actors that simulate agents on levels: the algorithm's :data:`Evaluator`, spread out.

Each actor builds its domain (and loads its agent) once, then evaluates whatever it is sent.
Work is handed out in small chunks with a little back-pressure (``max_in_flight`` chunks queued
per actor), so an actor that drew a long episode does not hold up the rest of the batch and no
actor sits idle waiting for a round trip.

Two kinds of failure are kept apart:

* an evaluation that *raises* inside the actor comes back as a failed
  :class:`~dsage_ray.types.EvaluationResult` (the core retries it once, see
  :func:`dsage_ray.core.evaluation.evaluate_with_retry`);
* an actor that *dies* (killed, segfault, out of memory, node lost) is replaced and the chunks
  it had not returned are re-run on the pool. Every solution's result is accepted exactly once,
  so nothing is lost or counted twice.

Inside a Tune trial the actors land in the trial's placement group: Tune schedules the trainable
with ``placement_group_capture_child_tasks=True``, so child actors take the trial's bundles.
"""

from __future__ import annotations

import collections
import math
import dataclasses
import logging
import os
import time
from typing import Any, Callable, Sequence

import numpy as np
import ray
from ray.exceptions import RayActorError

from dsage_ray.agents.shipping import AgentFiles, config_agent_specs, install_agent_files, pack_agent_files
from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain, get_domain
from dsage_ray.errors import ResourceError
from dsage_ray.ray.session import start_ray
from dsage_ray.types import Domain, EvaluationResult, Solutions

logger = logging.getLogger(__name__)

#: Builds a domain from a run config inside each actor; must be picklable.
DomainFactory = Callable[[RunConfig], Domain]

#: Environment variables that cap the thread pools of the numeric libraries in an actor process.
#: Seconds to wait for every simulator actor to start before failing instead of hanging.
PLACEMENT_TIMEOUT_S = 120.0
_THREAD_ENV_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


class PoolResourceError(ResourceError):
    """The cluster cannot hold the requested simulators (raised instead of waiting forever)."""


@ray.remote
class SimulatorActor:
    """One simulator process: builds the domain once and evaluates chunks of solutions.

    Args:
        config: The run config the domain is built from.
        domain_factory: Builds the domain (``build_domain`` unless a test injects one).
        num_threads: Torch intra-op threads for this process.
        agent_files: The bytes of the files the config's agent specs name (:mod:`dsage_ray.agents.shipping`):
            unpacked here before the domain loads its agent, so no node needs the driver's paths.
    """

    def __init__(self, config: RunConfig, domain_factory: DomainFactory, num_threads: int,
                 agent_files: Sequence[AgentFiles] = ()) -> None:
        install_agent_files(agent_files)
        # OMP_NUM_THREADS & co. are already in the process environment (runtime_env) so that
        # OpenBLAS/MKL read them at import time; torch keeps its own pool size.
        try:
            import torch

            torch.set_num_threads(num_threads)
        except ImportError:  # pragma: no cover - torch is a dependency, but the pool does not need it.
            pass
        self._domain = domain_factory(config)

    def info(self) -> dict[str, Any]:
        """Where this actor runs; also the readiness probe (it answers once ``__init__`` finished)."""
        context = ray.get_runtime_context()
        return {
            "pid": os.getpid(),
            "node_id": context.get_node_id(),
            "placement_group_id": context.get_placement_group_id(),
            "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
            "num_measures": len(self._domain.measure_names),
            "occupancy_shape": tuple(self._domain.occupancy_shape),
        }

    def evaluate(self, solutions: Solutions, seeds: Sequence[int]) -> list[EvaluationResult]:
        from dsage_ray.core.evaluation import evaluate_safely

        return [evaluate_safely(self._domain, solution, int(seed)) for solution, seed in zip(solutions, seeds)]


@dataclasses.dataclass
class PoolStats:
    """Counters over the pool's lifetime (reported by the trainable, checked by the tests)."""

    evaluations: int = 0
    failed_evaluations: int = 0
    actor_deaths: int = 0
    resubmitted_chunks: int = 0


class SimulatorPool:
    """Evaluates batches of solutions on ``num_workers`` Ray actors; an :data:`Evaluator`.

    Args:
        config: The run config; each actor builds its domain from it. ``config.ray`` supplies the
            defaults of the other arguments.
        num_workers: Number of simulator actors.
        cpus_per_worker: Logical CPUs each actor reserves (fractions allowed).
        chunk_size: Solutions per task; 0 picks about 8 chunks per actor for each batch.
        max_in_flight: Chunks queued per actor; 2 hides the round trip behind the current chunk.
        domain_factory: Builds the domain inside each actor.
        placement_timeout_s: How long to wait for all actors to start before failing.
        max_deaths_per_chunk: A chunk whose actor died this many times is returned as failed
            (e.g. a level that crashes the simulator) instead of killing actors forever.
        agent_files: The bytes of the files the config's agent specs name (default: read from their paths here);
            every actor installs them, so none opens those paths (:mod:`dsage_ray.agents.shipping`).

    Raises:
        PoolResourceError: The cluster (or the enclosing placement group) cannot hold the actors.
    """

    #: The simulators are other processes: a pipelined run overlaps its surrogate's work with a batch
    #: (:class:`~dsage_ray.core.evaluation.PendingEvaluation`).
    runs_elsewhere = True

    def __init__(
        self,
        *,
        config: RunConfig,
        num_workers: int | None = None,
        cpus_per_worker: float | None = None,
        chunk_size: int | None = None,
        max_in_flight: int = 2,
        domain_factory: DomainFactory = build_domain,
        placement_timeout_s: float | None = None,
        max_deaths_per_chunk: int = 3,
        agent_files: Sequence[AgentFiles] | None = None,
    ) -> None:
        self.config = config
        self.num_workers = config.ray.num_workers if num_workers is None else num_workers
        self.cpus_per_worker = config.ray.cpus_per_worker if cpus_per_worker is None else cpus_per_worker
        self.chunk_size = config.experimental.chunk_size if chunk_size is None else chunk_size
        self.max_in_flight = max_in_flight
        self.placement_timeout_s = PLACEMENT_TIMEOUT_S if placement_timeout_s is None else placement_timeout_s
        self.max_deaths_per_chunk = max_deaths_per_chunk
        self.domain_factory = domain_factory
        if self.num_workers < 1:
            raise ValueError(f"ray.num_workers: a pool needs at least one actor (got {self.num_workers})")
        if self.chunk_size < 0 or self.max_in_flight < 1:
            raise ValueError("chunk_size must be >= 0 (0: automatic) and max_in_flight positive")
        self.stats = PoolStats()
        self._closed = False

        start_ray()  # honours RAY_ADDRESS; a no-op inside a Tune trial (already connected)
        # Read once here (the driver, or the trial that received them), then sent with every actor that starts,
        # a replacement after a node loss included.
        self._agent_files = ray.put(tuple(agent_files) if agent_files is not None
                                    else pack_agent_files(config_agent_specs(config.to_dict())))
        self._in_placement_group = ray.util.get_current_placement_group() is not None
        if not self._in_placement_group:
            check_cluster_fits(bundles=[{"CPU": self.cpus_per_worker}] * self.num_workers,
                               what=f"a pool of {self.num_workers} simulator actors")
        self._threads = max(1, int(self.cpus_per_worker))
        self._actors = [self._new_actor() for _ in range(self.num_workers)]
        self._generations = [0] * self.num_workers
        self.actor_info = self._wait_until_ready()
        # Shapes for the failures the pool records itself (a chunk that kept killing its actor).
        self._num_measures = self.actor_info[0]["num_measures"]
        self._occupancy_shape = self.actor_info[0]["occupancy_shape"]

    # --------------------------------------------------------------------------------- actors

    def _new_actor(self):
        env = {name: str(self._threads) for name in _THREAD_ENV_VARS}
        actor_env = get_domain(self.config.domain).actor_env
        if actor_env is not None:
            env.update(actor_env())  # e.g. Mario's JVM: signal chaining beside Ray's faulthandler
        return SimulatorActor.options(
            num_cpus=self.cpus_per_worker,
            runtime_env={"env_vars": env},
        ).remote(self.config, self.domain_factory, self._threads, self._agent_files)

    def _wait_until_ready(self) -> list[dict[str, Any]]:
        """Blocks until every actor has built its domain; fails clearly instead of hanging."""
        probes = [actor.info.remote() for actor in self._actors]
        ready, pending = ray.wait(probes, num_returns=len(probes), timeout=self.placement_timeout_s)
        if pending:
            self.close()
            where = ("the trial's placement group" if self._in_placement_group
                     else f"the cluster (available: {ray.available_resources().get('CPU', 0):g} CPU)")
            raise PoolResourceError(
                f"only {len(ready)} of {self.num_workers} simulator actors "
                f"({self.cpus_per_worker:g} CPU each) started within {self.placement_timeout_s:g}s "
                f"in {where}. Either they do not fit (lower ray.num_workers or ray.cpus_per_worker, or add "
                f"nodes), or they are still starting: Ray runs its workers at a low priority (niceness 15, "
                f"RAY_worker_niceness), so on a machine busy with other processes, importing torch and building "
                f"the domain can take minutes (SimulatorPool's placement_timeout_s)")
        try:
            return ray.get(probes)
        except RayActorError as exc:
            self.close()
            raise RuntimeError(f"a simulator actor failed to build its domain: {exc}") from exc

    def _replace(self, slot: int) -> None:
        """Kills (if not already dead) and replaces the actor in ``slot``."""
        self.stats.actor_deaths += 1
        try:
            ray.kill(self._actors[slot], no_restart=True)
        except Exception:  # noqa: BLE001 - it is usually dead already; that is the point.
            pass
        self._actors[slot] = self._new_actor()
        self._generations[slot] += 1
        logger.warning("simulator actor %d died; replaced it and re-running its unfinished work", slot)

    # ------------------------------------------------------------------------------ evaluating

    def __call__(self, solutions: Solutions, seeds: Sequence[int]) -> list[EvaluationResult]:
        """Evaluates ``solutions[i]`` with ``seeds[i]``; results come back in submission order."""
        return self.evaluate_until(solutions, seeds)

    def evaluate_until(self, solutions: Solutions, seeds: Sequence[int], *, deadline: float | None = None,
                       progress: Callable[[int], None] | None = None) -> list[EvaluationResult]:
        """Evaluates the batch, or once ``deadline`` (a :func:`time.perf_counter` value) has passed, the chunks
        already handed out: a prefix of the batch, in submission order.

        The chunks of an actor that died are re-run whatever the deadline, so the prefix has no hole.
        ``progress`` hears the number of results in after each chunk.
        """
        if self._closed:
            raise RuntimeError("the simulator pool is closed")
        solutions = np.asarray(solutions)
        n = len(solutions)
        if len(seeds) != n:
            raise ValueError(f"got {n} solutions but {len(seeds)} seeds")
        results: list[EvaluationResult | None] = [None] * n
        size = self.chunk_size or self._auto_chunk_size(n)
        todo = collections.deque((start, min(start + size, n)) for start in range(0, n, size))
        deaths: collections.Counter[tuple[int, int]] = collections.Counter()
        # ref -> (slot, generation of the actor it was sent to, chunk)
        in_flight: dict[ray.ObjectRef, tuple[int, int, tuple[int, int]]] = {}
        load = [0] * self.num_workers

        handed_out = 0  # solutions [0, handed_out) were sent at least once; the rest are still fresh
        while todo or in_flight:
            if deadline is not None and handed_out and time.perf_counter() >= deadline:
                # Out of time: no fresh chunk starts; re-runs of a dead actor's chunks (all below) still do.
                todo = collections.deque(chunk for chunk in todo if chunk[0] < handed_out)
                if not todo and not in_flight:
                    break
            # Hand out work to the least-loaded live actors, up to max_in_flight each.
            while todo:
                slot = min(range(self.num_workers), key=load.__getitem__)
                if load[slot] >= self.max_in_flight:
                    break
                chunk = todo.popleft()
                handed_out = max(handed_out, chunk[1])
                ref = self._actors[slot].evaluate.remote(solutions[chunk[0]:chunk[1]], list(seeds[chunk[0]:chunk[1]]))
                in_flight[ref] = (slot, self._generations[slot], chunk)
                load[slot] += 1

            (ref,), _ = ray.wait(list(in_flight), num_returns=1)
            slot, generation, chunk = in_flight.pop(ref)
            try:
                chunk_results = ray.get(ref)
            except RayActorError:
                # Only the first failed ref of a dead actor replaces it; its other refs fail too.
                if generation == self._generations[slot]:
                    self._replace(slot)
                    load[slot] = 0
                deaths[chunk] += 1
                if deaths[chunk] >= self.max_deaths_per_chunk:
                    self._fill_failed(results, chunk, f"the simulator process died {deaths[chunk]} times")
                else:
                    self.stats.resubmitted_chunks += 1
                    todo.appendleft(chunk)
                continue
            if generation == self._generations[slot]:
                load[slot] -= 1
            for offset, result in enumerate(chunk_results):
                self._accept(results, chunk[0] + offset, result)
            if progress is not None:
                progress(sum(r is not None for r in results))

        results = results[:handed_out]
        assert all(r is not None for r in results)
        return results  # type: ignore[return-value]

    def _accept(self, results: list[EvaluationResult | None], index: int, result: EvaluationResult) -> None:
        if results[index] is not None:  # a bug, never a fault to tolerate: it would double-count
            raise RuntimeError(f"solution {index} was evaluated twice")
        results[index] = result
        self.stats.evaluations += 1
        self.stats.failed_evaluations += int(result.failed)

    def _auto_chunk_size(self, n: int) -> int:
        """About 8 chunks per actor: few enough round trips that the ~1–3 ms per task stays small
        next to cheap evaluations, enough chunks that uneven episode lengths still even out."""
        return max(1, math.ceil(n / (8 * len(self._actors))))

    def _fill_failed(self, results: list[EvaluationResult | None], chunk: tuple[int, int], error: str) -> None:
        for index in range(*chunk):
            self._accept(results, index, EvaluationResult.failure(
                error=error, num_measures=self._num_measures, occupancy_shape=self._occupancy_shape))


    # ------------------------------------------------------------------------------- lifetime

    def actor_handles(self) -> list[Any]:
        """The live actor handles (tests kill them to simulate faults)."""
        return list(self._actors)

    def close(self) -> None:
        """Kills the actors and frees their resources; the pool cannot be used afterwards."""
        if self._closed:
            return
        self._closed = True
        for actor in self._actors if hasattr(self, "_actors") else []:
            try:
                ray.kill(actor, no_restart=True)
            except Exception:  # noqa: BLE001 - closing must not fail on an already-dead actor
                pass
        # Drop the handles now: released later, their __del__ can run inside the SIGTERM Tune sends a
        # finished trial and print a "SystemExit" traceback that means nothing.
        self._actors = []

    def __enter__(self) -> "SimulatorPool":
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()


def check_cluster_fits(*, bundles: list[dict[str, float]], what: str,
                       nodes: list[dict[str, float]] | None = None) -> None:
    """Raises :class:`PoolResourceError` when ``bundles`` can never be placed on this cluster.

    Checks the total and that each bundle fits on at least one node, so a misconfigured request
    fails immediately instead of pending forever (Ray would wait for an autoscaler).

    Args:
        bundles: Resource bundles, e.g. ``[{"CPU": 1.0}, {"CPU": 0.5}, ...]``.
        what: Names the request in the error message.
        nodes: The resources of each node; default: the alive nodes of the connected cluster
            (given, the check runs before Ray starts).
    """
    if nodes is None:
        nodes = [node["Resources"] for node in ray.nodes() if node.get("Alive")]
    total = {key: sum(node.get(key, 0.0) for node in nodes) for key in {k for node in nodes for k in node}}
    for key in sorted({k for bundle in bundles for k in bundle}):
        need = sum(bundle.get(key, 0.0) for bundle in bundles)
        have = total.get(key, 0.0)
        if need > have + 1e-9:
            raise PoolResourceError(
                f"{what} needs {need:g} {key} in all but the Ray cluster has {have:g} "
                f"({len(nodes)} node(s)); lower ray.num_workers / ray.cpus_per_worker / ray.trial_cpus "
                f"or add nodes")
    for bundle in bundles:
        if not any(all(node.get(k, 0.0) + 1e-9 >= v for k, v in bundle.items()) for node in nodes):
            raise PoolResourceError(f"{what}: no node of the Ray cluster can hold a bundle {bundle}")
