"""A series of checkpoints audited in training order: a regression suite that grows, and a short search each.

:class:`AuditSeries` is what ``dsage-ray audit-series`` and a training callback call for each new checkpoint
of an agent (``series.audit(spec, label=..., step=...)``). For checkpoint ``k`` it

1. **re-evaluates the regression suite** on the checkpoint: every level that an earlier checkpoint's audit
   found failing, each with the seed recorded when it was found (:func:`~dsage_ray.audit.collection.reevaluate`,
   the checkpoint's :func:`~dsage_ray.audit.collection.audit_config`, ``episodes`` per level). A level is
   **failing** when its failure rate ``1 - success_rate`` is at least
   :data:`~dsage_ray.audit.summary.FAILURE_CELL_RATE` (0.5; with 5 episodes: at most 2 successes), the rule of
   the collection's "failure cells". A level is **fixed** when it was failing at its previous result (normally
   checkpoint ``k - 1``'s) and is not now, **regressed** when the reverse;
2. **runs a short audit** (:func:`~dsage_ray.audit.run.run_audit`, ``budget`` evaluations, run seed
   ``seed + k``, so that each checkpoint's search starts from other random levels) into
   ``out_dir/checkpoints/<k>-<label>``. With ``warm_start``, the search of checkpoint ``k > 0`` starts from the
   surrogate of the last audit that succeeded (``surrogate.init`` = that audit's folder; its dataset is only
   a prior, :mod:`dsage_ray.core.warm_start`);
3. adds the **new failures** to the suite: the audit's collection levels that are failing and whose solution
   (its bytes) is not in the suite yet, each with its collection seed; their success at checkpoint ``k`` is
   the collection's number for that seed;
4. writes ``series.json`` (atomically), ``series.html`` (:mod:`dsage_ray.audit.series_report`) and the
   record's TensorBoard scalars (``out_dir/tensorboard``, step = the record's ``step``, else its index).

A checkpoint whose audit raises (its agent does not load, its search fails) is recorded with ``error`` and a
single warning line in the log; the series goes on. A checkpoint already recorded (the same ``label`` and
``agent``) is not audited again: running the same command again continues the series where it stopped.

The default ``budget`` is a quarter of the preset's, and at least ``n_rand + selection.count`` (the random
start and one outer iteration of a cold search): ``cpu`` 1,000, ``demo`` 150, ``tiny`` 70 (Maze).

Series folder::

    series.json                       settings, one record per checkpoint, the suite (levels, seeds, results)
    series.html                       timeline, table per checkpoint, level x checkpoint matrix
    checkpoints/000-<label>/          each checkpoint's audit folder (search/, collection/report.html)
    tensorboard/                      audit/... scalars per checkpoint
"""

from __future__ import annotations

import dataclasses
import logging
import os
import shutil
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from dsage_ray.audit.collection import agent_slug, audit_config, audit_spec, reevaluate
from dsage_ray.audit.run import default_preset, run_audit
from dsage_ray.audit.summary import FAILURE_CELL_RATE
from dsage_ray.domains.registry import DEFAULT_DOMAIN
from dsage_ray.errors import InputError, describe
from dsage_ray.io import atomic_write_json

SERIES_FILE = "series.json"
SERIES_REPORT = "series.html"
#: ``format`` of ``series.json``.
SERIES_FORMAT = "dsage_ray.series.v1"
#: Sub-folders of a series folder: the checkpoints' audits, the TensorBoard scalars.
CHECKPOINTS_DIR, TENSORBOARD_DIR = "checkpoints", "tensorboard"
#: The default budget is the preset's divided by this (at least ``n_rand + selection.count``).
BUDGET_DIVISOR = 4
#: The rule of :func:`is_failing`, as ``series.json`` and the report state it.
FAILING_RULE = f"failure rate (1 - success rate) >= {FAILURE_CELL_RATE:g}"

log = logging.getLogger(__name__)


def is_failing(success_rate: float) -> bool:
    """Whether a level counts as failing for the suite: failure rate ``>=`` :data:`FAILURE_CELL_RATE`."""
    return 1.0 - float(success_rate) >= FAILURE_CELL_RATE


def fixed_and_regressed(previous: Mapping[int, float], current: Mapping[int, float]) -> tuple[tuple[int, ...],
                                                                                           tuple[int, ...]]:
    """Levels that stopped failing and levels that started, between two results per level id.

    Args:
        previous: Success rate per level id at the earlier checkpoint.
        current: Success rate per level id now.

    Returns:
        ``(fixed, regressed)``, sorted level ids; levels missing from either mapping are in neither.
    """
    both = sorted(set(previous) & set(current))
    fixed = tuple(i for i in both if is_failing(previous[i]) and not is_failing(current[i]))
    regressed = tuple(i for i in both if not is_failing(previous[i]) and is_failing(current[i]))
    return fixed, regressed


def default_budget(config) -> int:
    """A quarter of ``config.budget``, at least ``n_rand + selection.count`` (module docstring)."""
    return max(int(config.budget) // BUDGET_DIVISOR, int(config.n_rand) + int(config.selection.count))


@dataclasses.dataclass(frozen=True, kw_only=True)
class SeriesRecord:
    """One checkpoint of a series, as it was audited.

    Attributes:
        index: Its place in the series (0 first).
        label: Its name in the series (the report, the folder, resuming).
        agent: The agent spec audited.
        step: Training step (environment steps) it was taken at, when known.
        suite_size: Levels of the regression suite re-evaluated for this checkpoint.
        suite_success_rate: Mean success rate over them (None when the suite was empty).
        fixed: Suite level ids failing at their previous result, not failing now.
        regressed: Suite level ids not failing at their previous result, failing now.
        new_failures: Levels this checkpoint's search added to the suite.
        summary: The audit collection's failure summary (``levels``, ``never_solved``, ``failure_cells``, ...).
        audit_dir: This checkpoint's audit folder (None when none was started).
        wall_time: Seconds the checkpoint took (suite and audit).
        error: Why the audit of this checkpoint failed (one line), else None; the suite's numbers are kept
            when they were measured before the failure, the rest is empty.
    """

    index: int
    label: str
    agent: str
    step: int | None
    suite_size: int
    suite_success_rate: float | None
    fixed: tuple[int, ...]
    regressed: tuple[int, ...]
    new_failures: int
    summary: Mapping[str, Any]
    audit_dir: str | None
    wall_time: float
    error: str | None

    def scalars(self) -> dict[str, float]:
        """The record as TensorBoard scalars (``audit/...``); numbers that were not measured are left out."""
        out: dict[str, float] = {}
        if self.suite_success_rate is not None:
            out["audit/suite_success_rate"] = float(self.suite_success_rate)
        if self.suite_size or self.error is None:
            out["audit/fixed"] = float(len(self.fixed))
            out["audit/regressed"] = float(len(self.regressed))
        if self.error is None:
            out["audit/new_failures"] = float(self.new_failures)
        for key in ("never_solved", "failure_cells"):
            if self.summary.get(key) is not None:
                out[f"audit/{key}"] = float(self.summary[key])
        out["audit/wall_time"] = float(self.wall_time)
        return out

    def to_json(self, root: Path) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["fixed"], data["regressed"] = list(self.fixed), list(self.regressed)
        data["summary"] = dict(self.summary)
        data["audit_dir"] = None if self.audit_dir is None else os.path.relpath(self.audit_dir, root)
        return data

    @classmethod
    def from_json(cls, data: Mapping[str, Any], root: Path) -> "SeriesRecord":
        return cls(index=int(data["index"]), label=str(data["label"]), agent=str(data["agent"]),
                   step=None if data.get("step") is None else int(data["step"]),
                   suite_size=int(data["suite_size"]),
                   suite_success_rate=(None if data.get("suite_success_rate") is None
                                       else float(data["suite_success_rate"])),
                   fixed=tuple(int(i) for i in data["fixed"]), regressed=tuple(int(i) for i in data["regressed"]),
                   new_failures=int(data["new_failures"]), summary=dict(data.get("summary") or {}),
                   audit_dir=None if data.get("audit_dir") is None else str(root / data["audit_dir"]),
                   wall_time=float(data["wall_time"]), error=data.get("error"))


@dataclasses.dataclass(kw_only=True)
class SuiteLevel:
    """A level of the regression suite.

    Attributes:
        id: Its id in the suite (0 first; never reused).
        solution: The level, as the domain's solution array.
        seed: The evaluation seed it is re-evaluated with (the one its audit's collection recorded).
        origin: Index of the checkpoint whose audit found it.
        level_file: Its level file in that audit's collection, relative to the series folder.
        results: Success rate per checkpoint index, from ``origin`` on (missing where its evaluation failed).
    """

    id: int
    solution: np.ndarray
    seed: int
    origin: int
    level_file: str | None
    results: dict[int, float]

    def latest_before(self, index: int) -> float | None:
        """Its success rate at the last checkpoint before ``index`` that measured it."""
        earlier = [k for k in self.results if k < index]
        return self.results[max(earlier)] if earlier else None

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "seed": self.seed, "origin": self.origin, "level_file": self.level_file,
                "results": {str(k): v for k, v in sorted(self.results.items())},
                "solution": np.asarray(self.solution).tolist()}

    @classmethod
    def from_json(cls, data: Mapping[str, Any], dtype) -> "SuiteLevel":
        return cls(id=int(data["id"]), seed=int(data["seed"]), origin=int(data["origin"]),
                   level_file=data.get("level_file"), results={int(k): float(v) for k, v in data["results"].items()},
                   solution=np.asarray(data["solution"], dtype=dtype))


class AuditSeries:
    """Audits checkpoints of one agent in training order, with a regression suite (module docstring).

    Args:
        out_dir: The series folder. One holding a ``series.json`` is continued (its records and suite);
            otherwise a new series starts there (the folder is created by the first checkpoint).
        domain: A domain that declares audits (``maze``, ``mario``, a plug-in's).
        preset: The domain's preset of every audit (default :func:`~dsage_ray.audit.run.default_preset`
            of a named agent: ``cpu``).
        budget: Real evaluations of each checkpoint's search (default :func:`default_budget`).
        seed: Run seed; checkpoint ``k``'s search runs with ``seed + k``.
        overrides: Dotted config keys of every audit, like ``--set``.
        local: Search and evaluate in this process instead of through Ray.
        workers: Simulator actors (``ray.num_workers``) of the searches and the suite's re-evaluation.
        address: A Ray cluster to join.
        episodes: Episodes per level, in the collections and the suite's re-evaluation (default: the config's).
        warm_start: Start each search after the first from the previous audit's surrogate. A
            ``surrogate.init`` in ``overrides`` wins over it: every search then starts from that source.

    Raises:
        InputError: An unknown domain or preset, a bad config key, a non-positive ``budget``/``episodes``, or
            an ``out_dir`` whose series is of another domain.
    """

    def __init__(self, *, out_dir: str | os.PathLike[str], domain: str = DEFAULT_DOMAIN, preset: str | None = None,
                 budget: int | None = None, seed: int = 0, overrides: Mapping[str, Any] | None = None,
                 local: bool = False, workers: int | None = None, address: str | None = None,
                 episodes: int | None = None, warm_start: bool = True) -> None:
        for name, value in (("budget", budget), ("episodes", episodes)):
            if value is not None and value < 1:
                raise InputError(f"{name} must be positive, got {value}")
        if workers is not None and workers < 0:
            raise InputError(f"workers must be >= 0 (0: simulate in the search process), got {workers}")
        self.out_dir = Path(out_dir)
        self.domain = domain
        self.spec = audit_spec(domain)
        self.preset = preset or default_preset(domain, agent=self.spec.audit.default_agent)
        self.seed = int(seed)
        self.overrides = dict(overrides or {})
        self.local, self.workers, self.address = local, workers, address
        self.episodes = episodes
        self.warm_start = warm_start
        # Every key, the preset and the overrides checked now, with the domain's own agent (nothing loads).
        base = self._config(None)
        self.budget = int(budget or self.overrides.get("budget") or default_budget(base))
        self.episodes_used = int(self.episodes or _config_value(base, self.spec.audit.episodes_key))
        self.records: list[SeriesRecord] = []
        self.suite: list[SuiteLevel] = []
        self._load()

    # ------------------------------------------------------------------------------------------ paths

    @property
    def series_path(self) -> Path:
        return self.out_dir / SERIES_FILE

    @property
    def report_path(self) -> Path:
        return self.out_dir / SERIES_REPORT

    @property
    def tensorboard_dir(self) -> Path:
        return self.out_dir / TENSORBOARD_DIR

    # ---------------------------------------------------------------------------------------- public

    def config_for(self, agent: str | None):
        """The audit config of ``agent`` in this series (its kind checked against the domain, nothing loaded).

        Raises:
            ValueError: The domain does not play ``agent``'s kind, or a config key is bad.
        """
        return self._config(agent)

    def recorded(self, agent: str, label: str | None = None) -> SeriesRecord | None:
        """The record of the checkpoint ``(label or agent, agent)``, if the series holds one."""
        label = label or agent
        return next((r for r in self.records if r.agent == agent and r.label == label), None)

    def audit(self, agent: str, *, label: str | None = None, step: int | None = None) -> SeriesRecord:
        """Audits the checkpoint ``agent`` as the series' next one (module docstring), unless recorded.

        Args:
            agent: The checkpoint's agent spec (``rllib:PATH``, ``dcd:PATH``, ...).
            label: Its name in the series (default: ``agent``).
            step: The training step it was taken at (TensorBoard's step; default the record's index).

        Returns:
            Its record: the one already in the series for ``(label, agent)``, else the new one. An audit
            that raised is a record with ``error`` (and one warning in the log), never an exception.
        """
        label = label or agent
        done = self.recorded(agent, label)
        if done is not None:
            log.info("audit-series: %s already recorded as checkpoint %d, skipped", label, done.index)
            return done
        index = len(self.records)
        started = time.time()
        audit_dir = self.out_dir / CHECKPOINTS_DIR / f"{index:03d}-{agent_slug(label)}"
        state: dict[str, Any] = {"suite_size": 0, "suite_success_rate": None, "fixed": (), "regressed": (),
                                 "results": {}}
        try:
            added, summary = self._audit(agent, index=index, audit_dir=audit_dir, state=state)
        except Exception as exc:  # noqa: BLE001 - one failed checkpoint must never lose the series
            message = describe(exc)[1]
            log.warning("audit-series: checkpoint %d (%s) failed, the series goes on: %s", index, label, message)
            added, summary, error = [], {}, message
        else:
            error = None
        # The suite's numbers of this checkpoint are kept when they were measured, even if the search failed.
        for level in self.suite:
            if level.id in state["results"]:
                level.results[index] = state["results"][level.id]
        self.suite += added
        record = SeriesRecord(
            index=index, label=label, agent=agent, step=step, suite_size=state["suite_size"],
            suite_success_rate=state["suite_success_rate"], fixed=tuple(state["fixed"]),
            regressed=tuple(state["regressed"]), new_failures=len(added), summary=summary,
            audit_dir=str(audit_dir) if audit_dir.exists() else None, wall_time=time.time() - started, error=error)
        self.records.append(record)
        self._save()
        self._log_scalars(record)
        try:
            self.write_report()
        except Exception as exc:  # noqa: BLE001 - the page is a view; series.json holds everything
            log.warning("audit-series: could not write %s: %s", self.report_path, describe(exc)[1])
        return record

    def write_report(self) -> Path:
        """Writes ``series.html`` (:mod:`dsage_ray.audit.series_report`) and returns its path."""
        from dsage_ray.audit.series_report import write_series_report

        return write_series_report(self.out_dir, self.to_json())

    def to_json(self) -> dict[str, Any]:
        """What ``series.json`` holds."""
        return {
            "format": SERIES_FORMAT,
            "domain": self.domain,
            "preset": self.preset,
            "budget": self.budget,
            "seed": self.seed,
            "episodes": self.episodes_used,
            "overrides": self.overrides,
            "warm_start": self.warm_start,
            "failing": FAILING_RULE,
            "updated": time.strftime("%Y-%m-%d %H:%M:%S"),
            "records": [r.to_json(self.out_dir) for r in self.records],
            "suite": [level.to_json() for level in self.suite],
        }

    # --------------------------------------------------------------------------------------- private

    def _config(self, agent: str | None, *, index: int = 0, extra: Mapping[str, Any] | None = None):
        overrides = dict(self.overrides)
        if self.episodes is not None:
            overrides[self.spec.audit.episodes_key] = int(self.episodes)
        if self.workers is not None:
            overrides["ray.num_workers"] = int(self.workers)
        overrides.update(extra or {})
        budget = getattr(self, "budget", None)
        return audit_config(domain=self.domain, agent=agent, preset=self.preset, seed=self.seed + index,
                            budget=budget, overrides=overrides)

    def _audit(self, agent: str, *, index: int, audit_dir: Path, state: dict[str, Any]) -> tuple[list, dict]:
        """Steps 1-3 of the module docstring; fills ``state`` as the suite's numbers become known."""
        from dsage_ray.domains import build_domain
        from dsage_ray.preflight import preflight

        config = self._config(agent, index=index)
        preflight(config)  # the agent loads, or this checkpoint fails here in one line
        domain = build_domain(config)

        # 1. The suite, with each level's recorded seed.
        if self.suite:
            solutions = np.stack([np.asarray(level.solution, dtype=domain.solution_dtype) for level in self.suite])
            results = self._evaluate(config, domain, solutions, [level.seed for level in self.suite],
                                     desc=f"checkpoint {index}: the regression suite")
            now = {level.id: float(domain.success_rate(result))
                   for level, result in zip(self.suite, results) if not result.failed}
            before = {level.id: level.latest_before(index) for level in self.suite}
            state["fixed"], state["regressed"] = fixed_and_regressed(
                {i: v for i, v in before.items() if v is not None}, now)
            state["results"] = now
            state["suite_size"] = len(self.suite)
            state["suite_success_rate"] = float(np.mean(list(now.values()))) if now else None

        # 2. A short search, warm-started from the last audit that succeeded.
        overrides = dict(self.overrides)
        warm_from = next((r.audit_dir for r in reversed(self.records) if r.error is None and r.audit_dir), None)
        if self.warm_start and warm_from and "surrogate.init" not in overrides and config.uses_surrogate:
            overrides["surrogate.init"] = warm_from
        if audit_dir.exists():  # an audit of this checkpoint that was interrupted before it was recorded
            shutil.rmtree(audit_dir)
        # A series follows training, whose early checkpoints fail the nominal level by rights: their check is
        # printed and recorded in their collection, and does not stop the series.
        collection = run_audit(agent=agent, domain=self.domain, preset=self.preset, budget=self.budget,
                               seed=self.seed + index, overrides=overrides, out=audit_dir, local=self.local,
                               workers=self.workers, address=self.address, episodes=self.episodes,
                               allow_failing_nominal=True)

        # 3. Its failing levels that the suite does not hold yet.
        known = {np.asarray(level.solution, dtype=domain.solution_dtype).tobytes() for level in self.suite}
        added: list[SuiteLevel] = []
        next_id = max((level.id for level in self.suite), default=-1) + 1
        for level in collection.levels:
            if not is_failing(level.success_rate):
                continue
            solution = np.asarray(domain.entry_solution(dict(level.fields), collection.path),
                                  dtype=domain.solution_dtype)
            key = solution.tobytes()
            if key in known:
                continue
            known.add(key)
            added.append(SuiteLevel(id=next_id + len(added), solution=solution, seed=level.seed, origin=index,
                                    level_file=os.path.relpath(level.level_path, self.out_dir),
                                    results={index: float(level.success_rate)}))
        return added, dict(collection.summary)

    def _evaluate(self, config, domain, solutions, seeds: Sequence[int], *, desc: str) -> list:
        """The suite on ``domain``'s agent: in this process (``local`` or no workers), else on a Ray pool."""
        from dsage_ray.core.evaluation import InProcessEvaluator

        if self.local or config.ray.num_workers == 0:
            return reevaluate(InProcessEvaluator(domain=domain, threads=config.torch_threads), solutions, seeds,
                              desc=desc)
        from dsage_ray.ray.session import start_ray
        from dsage_ray.ray.pool import SimulatorPool

        start_ray(self.address)
        pool = SimulatorPool(config=config)
        try:
            return reevaluate(pool, solutions, seeds, desc=desc)
        finally:
            pool.close()

    def _load(self) -> None:
        if not self.series_path.is_file():
            return
        import json

        try:
            data = json.loads(self.series_path.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"{self.series_path}: not a readable series ({describe(exc)[1]})") from None
        if data.get("format") != SERIES_FORMAT:
            raise InputError(f"{self.series_path}: not a series of this version (format {data.get('format')!r})")
        if data.get("domain") != self.domain:
            raise InputError(f"{self.out_dir} holds a series of domain {data.get('domain')!r}, not {self.domain!r}: "
                             f"choose another out folder")
        from dsage_ray.domains import build_domain

        dtype = build_domain(self._config(None)).solution_dtype  # building a domain loads no agent
        self.records = [SeriesRecord.from_json(r, self.out_dir) for r in data["records"]]
        self.suite = [SuiteLevel.from_json(level, dtype) for level in data["suite"]]

    def _save(self) -> None:
        atomic_write_json(self.series_path, self.to_json())

    def _log_scalars(self, record: SeriesRecord) -> None:
        try:
            from torch.utils.tensorboard import SummaryWriter

            writer = SummaryWriter(log_dir=str(self.tensorboard_dir))
            try:
                step = record.step if record.step is not None else record.index
                for key, value in record.scalars().items():
                    writer.add_scalar(key, value, global_step=step)
            finally:
                writer.close()
        except Exception as exc:  # noqa: BLE001 - TensorBoard is a view; series.json holds everything
            log.warning("audit-series: could not write TensorBoard scalars: %s", describe(exc)[1])


def _config_value(config, dotted: str) -> Any:
    value = config
    for part in dotted.split("."):
        value = getattr(value, part)
    return value

