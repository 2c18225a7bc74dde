"""A Tune callback that audits the checkpoints any trainable writes.

:class:`AuditCheckpointsCallback` runs in Tune's driver. Every ``audit_every``-th checkpoint a trial
reports (its 1st audited is checkpoint number ``audit_every``), it turns the checkpoint into an agent spec
with ``spec_from_checkpoint`` and audits it with that trial's :class:`~dsage_ray.audit.series.AuditSeries`
(``<out_dir>/<trial_id>/audit_series``): the regression suite re-evaluated, then a short warm-started DSAGE search.
The scalars go to a TensorBoard writer in the trial's own folder (``audit/...``, step = the trial's
environment steps when its results report them, else its training iteration), next to Tune's own event
files, so one TensorBoard shows both::

    from ray import tune
    from dsage_ray.integrations.tune import AuditCheckpointsCallback

    tuner = tune.Tuner("PPO", param_space=config, run_config=tune.RunConfig(
        callbacks=[AuditCheckpointsCallback(out_dir="tb_logs/audits", audit_every=2)],
        checkpoint_config=tune.CheckpointConfig(checkpoint_frequency=10)))

The default ``spec_from_checkpoint`` reads an RLlib algorithm checkpoint: it copies the module folder
(``learner_group/learner/rl_module/default_policy``) to ``<out_dir>/<trial_id>/checkpoints/<label>``, so
that the audited module outlives Tune's checkpoint clean-up (``num_to_keep``), and returns
``rllib:<copy>``. Any other trainer: pass a function from the checkpoint folder to a spec
(``lambda path: f"torchscript:{path}/policy.pt"``).

As for the RLlib callback, the audits run in the background by default, in one Ray actor per trial with a
CPU of its own (Tune's driver loop, which all trials wait on, only copies the module), one audit at a time per
trial; the experiment's end waits for the last ones. A failed audit logs one warning (``audit of <label>
skipped: <reason>``) and the trials go on. Leave a CPU free for the audit actor (``audit_cpus``), or
its audits wait for one.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable, Mapping

from ray.tune import Callback

from dsage_ray.integrations.auditor import SeriesAuditor
from dsage_ray.integrations.defaults import DEFAULT_AUDIT_BUDGET, DEFAULT_AUDIT_EVERY, SERIES_SUBDIR


def rllib_module_dir(checkpoint: str | os.PathLike[str], *, policy: str = "default_policy") -> Path:
    """The RLModule folder inside an RLlib algorithm checkpoint (or the folder itself, if it is a module)."""
    from dsage_ray.agents.rllib import resolve_module_dir

    return resolve_module_dir(str(checkpoint), policy=policy)


def rllib_spec(checkpoint: str | os.PathLike[str]) -> str:
    """``rllib:<module folder>`` of an RLlib algorithm checkpoint, without copying it."""
    return f"rllib:{rllib_module_dir(checkpoint).resolve()}"


def _trial_step(result: Mapping[str, Any]) -> int | None:
    from dsage_ray.integrations.rllib import env_steps

    step = env_steps(result)
    if step is None and result.get("training_iteration") is not None:
        step = int(result["training_iteration"])
    return step


class AuditCheckpointsCallback(Callback):
    """Audits every ``audit_every``-th checkpoint of every trial (module docstring).

    Args:
        out_dir: One folder per trial goes here (``<out_dir>/<trial_id>``: ``audit_series/``, ``checkpoints/``).
        audit_every: Audit checkpoints number ``audit_every``, ``2·audit_every``, ... of each trial.
        audit_budget: Real evaluations of each audit's search.
        spec_from_checkpoint: Checkpoint folder → agent spec; default: the copied RLlib module (above).
        tensorboard: Also write the scalars to the trial's folder.
        series: A factory called with the ``AuditSeries`` keyword arguments (``out_dir`` is the trial's
            series folder), e.g. for tests; default :class:`~dsage_ray.audit.series.AuditSeries`.
        **series_settings: ``background`` (default True), ``audit_cpus``, and each series' ``preset``,
            ``domain``, ``seed``, ``overrides``, ``local``, ``workers``, ``address``, ``episodes``, ``warm_start``.
    """

    def __init__(
        self,
        *,
        out_dir: str | os.PathLike[str],
        audit_every: int = DEFAULT_AUDIT_EVERY,
        audit_budget: int = DEFAULT_AUDIT_BUDGET,
        spec_from_checkpoint: Callable[[str], str] | None = None,
        tensorboard: bool = True,
        series: Callable[..., Any] | None = None,
        **series_settings: Any,
    ) -> None:
        if int(audit_every) < 1:
            raise ValueError(f"audit_every must be at least 1, got {audit_every}")
        self.out_dir = Path(out_dir)
        self.audit_every = int(audit_every)
        self.audit_budget = int(audit_budget)
        self.spec_from_checkpoint = spec_from_checkpoint
        self.tensorboard = tensorboard
        self.series = series
        self.series_settings = series_settings
        SeriesAuditor(out_dir=self.out_dir, audit_budget=self.audit_budget, series=series,
                      **series_settings)  # checks the settings
        #: Checkpoints seen per trial id.
        self.counts: dict[str, int] = {}
        #: ``(trial_id, label, record or None)`` of every audit that ended.
        self.audits: list[tuple[str, str, Any]] = []
        self._auditors: dict[str, SeriesAuditor] = {}

    def auditor(self, trial: Any) -> SeriesAuditor:
        """The trial's auditor (its series folder and writer), made on its first audit."""
        trial_id = str(trial.trial_id)
        if trial_id not in self._auditors:
            writer = None
            if self.tensorboard:
                writer = getattr(trial, "local_path", None) or getattr(trial, "path", None)
            self._auditors[trial_id] = SeriesAuditor(out_dir=self.out_dir / trial_id / SERIES_SUBDIR, series=self.series,
                                                     writer=writer, audit_budget=self.audit_budget,
                                                     **self.series_settings)
        return self._auditors[trial_id]

    def on_checkpoint(self, iteration: int, trials: list, trial: Any, checkpoint: Any, **info: Any) -> None:
        trial_id = str(trial.trial_id)
        self.counts[trial_id] = count = self.counts.get(trial_id, 0) + 1
        if count % self.audit_every:
            return
        result = dict(getattr(trial, "last_result", None) or {})
        iteration_done = result.get("training_iteration")
        label = f"iter_{iteration_done}" if iteration_done is not None else f"checkpoint_{count}"
        path = getattr(checkpoint, "path", checkpoint)
        try:
            auditor = self.auditor(trial)
        except Exception as exc:  # noqa: BLE001 - never stop the experiment
            from dsage_ray.integrations.faults import describe, log

            log.warning("audit of %s skipped: %s", label, describe(exc))
            self.audits.append((trial_id, label, None))
            return

        def spec() -> str:
            if self.spec_from_checkpoint is not None:
                return self.spec_from_checkpoint(str(path))
            import shutil

            copy = (self.out_dir / trial_id / "checkpoints" / label).resolve()
            if copy.exists():
                shutil.rmtree(copy)
            copy.parent.mkdir(parents=True, exist_ok=True)
            shutil.copytree(rllib_module_dir(path), copy)
            return f"rllib:{copy}"

        self._record(trial_id, auditor.submit(spec, label=label, step=_trial_step(result)))

    def on_step_begin(self, iteration: int, trials: list, **info: Any) -> None:
        for trial_id, auditor in self._auditors.items():
            if auditor.running:
                self._record(trial_id, auditor.poll())

    def on_experiment_end(self, trials: list, **info: Any) -> None:
        self.finish()

    def finish(self, timeout: float | None = None) -> None:
        """Waits for the audits still running (up to ``timeout`` s each) and ends their actors."""
        for trial_id, auditor in self._auditors.items():
            self._record(trial_id, auditor.finish(timeout=timeout))

    def _record(self, trial_id: str, finished: list) -> None:
        self.audits.extend((trial_id, audit.label, audit.record) for audit in finished)

    def __getstate__(self) -> dict:
        # Tune pickles its callbacks with the experiment; actors and writers stay in this process.
        return {**self.__dict__, "_auditors": {}}

    def get_state(self) -> dict | None:
        return {"counts": dict(self.counts)}

    def set_state(self, state: dict) -> None:
        self.counts = dict(state.get("counts", {}))
