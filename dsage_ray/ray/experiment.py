"""Running DSAGE trials with Ray Tune: one run, or a grid of variants × seeds (the paper's ablations).

Both of Tune's entry points are supported and share everything but the call itself:

* ``tune.run(...)`` — the classic function API;
* ``tune.Tuner(...).fit()`` — the current API, resumable with ``Tuner.restore``.

Every trial is a :class:`~dsage_ray.ray.trainable.DSAGETrainable` whose Tune config is a flat
:meth:`RunConfig.to_flat` dict, so any config key can be a grid axis (``variant``, ``seed``,
``surrogate.epochs``, ...): :func:`ablation_axes` reads ``--grid KEY=V1,V2`` and
:func:`grid_param_space` validates every grid point before Ray starts.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import re
from pathlib import Path
from typing import Any, Collection, Iterator, Literal, Mapping, Sequence

import ray
from ray import tune
from ray.air.constants import EXPR_ERROR_FILE
from ray.tune.logger import CSVLoggerCallback, JsonLoggerCallback

from dsage_ray.agents.shipping import config_agent_specs, pack_agent_files
from dsage_ray.config import ConfigError, RunConfig, key_hint, paper_comparison, parse_override, shown_value
from dsage_ray.core.checkpoint import CHECKPOINT_NAME
from dsage_ray.domains import build_domain
from dsage_ray.errors import InputError, Interrupted, TrialFailed
from dsage_ray.io import folder_lock
from dsage_ray.results import ExperimentResult, RunResult
from dsage_ray.ray.pool import DomainFactory, check_cluster_fits
from dsage_ray.ray.progress import ProgressLines, quiet_tune_output
from dsage_ray.ray.storage import local_copy, local_folder, storage_location
from dsage_ray.ray.trainable import DSAGETrainable, resource_request

#: Which Tune entry point runs the trials.
TuneApi = Literal["tuner", "run"]


class ExperimentInterrupted(Interrupted):
    """Tune returned before every trial spent its budget (Ctrl+C, a stopped driver)."""


#: A key that cannot be a grid axis, and why.
_NOT_AXES = {"domain": "one experiment searches one domain (the grid's explicit keys are relative to its defaults)"}


def parse_grid(text: str) -> tuple[str, list[Any]]:
    """``KEY=V1,V2,...`` (one ``--grid``) → ``(KEY, [V1, V2, ...])``.

    Each value is read as a ``--set`` value is (TOML, else a plain string), and a comma inside
    brackets or quotes belongs to its value: ``selection.block=[4,3],[8,6]`` has two values.

    Raises:
        ConfigError: No ``=``, no value, or a value given twice.
    """
    if "=" not in text:
        raise ConfigError(f"--grid {text!r}: expected KEY=V1,V2,...")
    key, raw = (part.strip() for part in text.split("=", 1))
    items = _split_top_level(raw)
    if not key or not all(items):
        raise ConfigError(f"--grid {text!r}: expected KEY=V1,V2,... with no empty value")
    values = [parse_override(f"{key}={item}")[1] for item in items]
    for i, value in enumerate(values):
        if value in values[:i]:
            raise ConfigError(f"--grid {key}: value {value!r} given twice")
    return key, values


def _split_top_level(raw: str) -> list[str]:
    """Splits at the commas that are outside brackets, braces and quotes."""
    items, depth, quote, start = [], 0, "", 0
    for i, char in enumerate(raw):
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            items.append(raw[start:i].strip())
            start = i + 1
    items.append(raw[start:].strip())
    return items


def ablation_axes(
    base: RunConfig,
    grid: Sequence[str] = (),
    *,
    variants: Sequence[str] | None = None,
    seeds: int | Sequence[int] | None = None,
    default_variants: Sequence[str] | None = None,
    default_seeds: int = 5,
) -> dict[str, list[Any]]:
    """The axes of an ablation: every ``--grid KEY=V1,V2``, plus ``variant`` and ``seed``.

    ``variant`` comes from ``--grid variant=...`` or ``variants``; without either it is
    ``default_variants`` (the domain's paper comparison unless given) when no other key is
    gridded, and the base config's own variant when one is (so ``--grid surrogate.epochs=50,200``
    does not also run the baselines that have no surrogate). ``seed`` comes from
    ``--grid seed=...`` or ``seeds`` (a count ``K`` means ``0..K-1``), else ``0..default_seeds-1``.

    Raises:
        ConfigError: A malformed ``--grid``, a key given twice, or ``variant``/``seed`` set both ways.
    """
    axes: dict[str, list[Any]] = {}
    for text in grid:
        key, values = parse_grid(text)
        if key in axes:
            raise ConfigError(f"--grid {key}: given twice; put all its values in one --grid {key}=V1,V2")
        axes[key] = values
    for key, flag, given in (("variant", "--variants", variants), ("seed", "--seeds", seeds)):
        if given is not None and key in axes:
            raise ConfigError(f"{flag} and --grid {key}=... both set the {key}s: pass one of them")
    if "variant" not in axes:
        if variants is not None:
            axes["variant"] = list(variants)
        elif set(axes) - {"seed"}:
            axes["variant"] = [base.variant]
        else:
            axes["variant"] = list(default_variants if default_variants is not None else paper_comparison(base.domain))
    if "seed" not in axes:
        seeds = default_seeds if seeds is None else seeds
        axes["seed"] = list(range(seeds)) if isinstance(seeds, int) else list(seeds)
    return axes


def grid_configs(base: RunConfig, axes: Mapping[str, Sequence[Any]]) -> tuple[dict[str, Any], list[RunConfig]]:
    """The base's explicit keys, and the validated config of every grid point.

    Explicit keys are those of the base that differ from the defaults of its ``(domain, preset,
    variant)``: each trial rebuilds its config with :meth:`RunConfig.build`, which applies the
    preset and variant layers of *its* grid point first, so a key the base merely inherits from
    its own variant must not pin the others. Grid keys are explicit in every point.

    Raises:
        ConfigError: An axis names an unknown key (with the closest keys) or a key that cannot be
            an axis, or a grid point's config is invalid (naming the point and the key).
    """
    known = base.to_flat()  # its own domain's section included
    for key, values in axes.items():
        if key in _NOT_AXES:
            raise ConfigError(f"--grid {key}: cannot be a grid axis: {_NOT_AXES[key]}")
        if key not in known:
            raise ConfigError(f"--grid {key}: unknown config key ({key_hint(key, known)})")
        if not values:
            raise ConfigError(f"--grid {key}: no values")
    layers = {"domain": base.domain, "preset": base.preset, "variant": base.variant}
    flat = base.to_flat()
    plain = RunConfig.build(layers).to_flat()
    section = {key: value for key, value in flat.items()
               if key.startswith(f"{base.domain}.") and plain.get(key) != value}
    # The defaults given the base's domain section: keys its section fills in from the others (a gym [fault]
    # space's search keys) are the base's defaults too, and each point's rebuild fills them in for its own variant.
    defaults = RunConfig.build({**layers, **section}).to_flat()
    explicit = {key: value for key, value in flat.items() if defaults.get(key) != value}
    explicit.update(section, domain=base.domain, preset=base.preset)
    configs = []
    for point in itertools.product(*axes.values()):
        values = dict(zip(axes, point))
        try:
            configs.append(RunConfig.build({**explicit, **values}))
        except ConfigError as exc:
            where = ", ".join(f"{key}={value!r}" for key, value in values.items() if len(axes[key]) > 1)
            raise ConfigError(f"grid point {where}: {exc}" if where else str(exc)) from None
    return explicit, configs


def grid_param_space(base: RunConfig, axes: Mapping[str, Sequence[Any]]) -> dict[str, Any]:
    """Tune's ``param_space`` for the grid: flat explicit keys, one ``tune.grid_search`` per axis.

    Every grid point is validated here, before Ray starts (see :func:`grid_configs`). An axis with
    a single value is a plain key, so trial names and progress lines show only what varies.
    """
    explicit, _ = grid_configs(base, axes)
    space = dict(explicit)
    for key, values in axes.items():
        space[key] = tune.grid_search(list(values)) if len(values) > 1 else values[0]
    return space


def check_resources(*configs: RunConfig, address: str | None = None) -> None:
    """Fails fast, naming the keys, when a trial's placement group can never be placed.

    Before Ray starts a local cluster (no ``address``, no ``RAY_ADDRESS``), the CPUs are checked
    against this machine's, so ``--workers 64`` on two cores costs no cluster start; once
    connected, everything is checked against the cluster's nodes. Each distinct request is
    checked once (a grid over ``ray.num_workers`` asks for several).

    Raises:
        PoolResourceError: A trial asks for more than the cluster (or this machine) has.
    """
    before_start = not ray.is_initialized() and not (address or os.environ.get("RAY_ADDRESS"))
    # What a local ray.init() will detect (cgroup limits included); other resources only once connected.
    nodes = [{"CPU": float(ray._private.utils.get_num_cpus())}] if before_start else None
    requests = {json.dumps(resource_request(config).bundles): config for config in configs}
    for config in requests.values():
        bundles = resource_request(config).bundles
        if before_start:
            bundles = [{"CPU": bundle.get("CPU", 0.0)} for bundle in bundles]
        check_cluster_fits(
            bundles=bundles,
            nodes=nodes,
            what=(f"one trial (ray.trial_cpus={config.ray.trial_cpus:g} + ray.num_workers={config.ray.num_workers} × "
                  f"ray.cpus_per_worker={config.ray.cpus_per_worker:g})"),
        )


def run_experiment(
    param_space: dict[str, Any],
    *,
    name: str,
    storage_path: str | Path,
    api: TuneApi = "tuner",
    resume: bool = False,
    max_failures: int = 2,
    domain_factory: DomainFactory = build_domain,
    verbose: int = 0,
    given: Collection[str] | None = None,
) -> ExperimentResult:
    """Runs every trial of ``param_space`` to its evaluation budget.

    Tune's own result logs are the CSV and JSON ones (``experiments/summarize.py`` reads them), without
    its TensorBoard logger: each trial writes its own ``dsage/*`` scalars against evaluations.

    Args:
        param_space: Flat Tune config (possibly with ``tune.grid_search`` axes).
        name: Experiment folder name under ``storage_path``.
        storage_path: Where results, checkpoints and TensorBoard files go (made absolute: Tune needs it).
        api: ``"tuner"`` (``tune.Tuner``) or ``"run"`` (``tune.run``).
        resume: Continue an interrupted experiment of the same name (unfinished and errored trials
            resume from their last checkpoints).
        max_failures: Times a crashed trial is restored from its last checkpoint.
        domain_factory: Builds the domain in the trial and in each simulator actor.
        verbose: Tune's own console verbosity (1 adds its status tables). A progress line per
            trial result is printed at every verbosity (:class:`~dsage_ray.ray.progress.ProgressLines`).
        given: With ``resume``, the keys the user gave (:func:`refuse_changed_config`); None: every key.

    Returns:
        The experiment folder and, per trial, its folder and latest checkpoint as Tune reports them.

    Raises:
        TrialFailed: A trial failed more than ``max_failures`` times (its error and ``error.txt``).
        ExperimentInterrupted: Tune returned before every trial finished.
    """
    storage_path = storage_location(storage_path)
    local = local_folder(storage_path)  # None: a remote filesystem (s3://, gs://), written and read through pyarrow
    if resume and local is not None:
        refuse_changed_config(local / name, param_space, given=given)
    # One writer per experiment folder (where it is a folder of this machine; a bucket cannot be locked).
    with folder_lock(local / name, what="experiment") if local is not None else contextlib.nullcontext():
        return _run_tune(param_space, name=name, storage_path=storage_path, api=api, resume=resume,
                         max_failures=max_failures, verbose=verbose,
                         domain_factory=domain_factory)


def _run_tune(param_space: Mapping[str, Any], *, name: str, storage_path: str, api: TuneApi, resume: bool,
              max_failures: int, verbose: int,
              domain_factory: DomainFactory | None) -> ExperimentResult:
    experiment_path = f"{storage_path.rstrip('/')}/{name}"
    # The agents travel as bytes (Tune puts these arguments in the object store): no trial needs the driver's paths.
    trainable = tune.with_parameters(DSAGETrainable, domain_factory=domain_factory,
                                     agent_files=pack_agent_files(config_agent_specs(param_space)))
    # Every outer iteration (a trial loses at most one), and at the end, so a finished trial's last state is on disk.
    checkpoint_config = tune.CheckpointConfig(checkpoint_frequency=1, checkpoint_at_end=True,
                                              num_to_keep=2)
    callbacks = [ProgressLines(), CSVLoggerCallback(), JsonLoggerCallback()]

    if api == "run":
        with quiet_tune_output(), _trial_failures():
            analysis = tune.run(
                trainable,
                name=name,
                config=param_space,
                storage_path=storage_path,
                checkpoint_config=checkpoint_config,
                max_failures=max_failures,
                resume="AUTO+ERRORED" if resume else False,
                verbose=verbose,
                callbacks=callbacks,
            )
        _check_finished(name, [trial.last_result for trial in analysis.trials])
        return ExperimentResult(path=Path(analysis.experiment_path), trials=tuple(
            _run_result(trial.config, trial.path, trial.checkpoint) for trial in analysis.trials))

    if resume and tune.Tuner.can_restore(experiment_path):
        tuner = tune.Tuner.restore(experiment_path, trainable=trainable, resume_errored=True)
    else:
        tuner = tune.Tuner(
            trainable,
            param_space=param_space,
            run_config=tune.RunConfig(
                name=name,
                storage_path=storage_path,
                checkpoint_config=checkpoint_config,
                failure_config=tune.FailureConfig(max_failures=max_failures),
                verbose=verbose,
                callbacks=callbacks,
            ),
        )
    with quiet_tune_output():
        results = tuner.fit()
    failed = [result for result in results if result.error is not None]
    if failed:
        raise trial_failed(len(failed), len(results), failed[0].error, Path(failed[0].path) / EXPR_ERROR_FILE)
    _check_finished(name, [result.metrics for result in results])
    return ExperimentResult(path=Path(results.experiment_path), trials=tuple(
        _run_result(result.config, result.path, result.checkpoint) for result in results))


def refuse_changed_config(experiment_path: Path, param_space: Mapping[str, Any], *,
                          given: Collection[str] | None = None) -> None:
    """Refuses a ``--resume`` whose config differs from the one the stored trials were started with.

    Tune restores each trial with its own config and never reopens a finished one, so a changed key (a
    larger ``budget``, another ``surrogate.epochs``) would be ignored without a word. This is the in-process
    rule too (a checkpoint only continues the config that wrote it), with the same one exception: a
    ``time_budget`` of 0 (none asked) keeps the trials' own. Grid axes are not compared (each trial holds one
    of their values).

    Args:
        experiment_path: The experiment folder (its ``*/params.json``).
        param_space: The flat config asked for now.
        given: The keys the user gave now (a config file's, ``--preset``, ``--set``, ``--workers``); only these
            are compared, so a default that changed since the experiment began does not stop it (its trials
            keep their own). None compares every key.

    Raises:
        InputError: Naming each differing key, the trials' values and the one asked for.
    """
    stored = [json.loads(path.read_text()) for path in sorted(experiment_path.glob("*/params.json"))]
    changes = []
    for key, asked in param_space.items():
        if isinstance(asked, Mapping) or (key == "time_budget" and asked == 0):
            continue  # a grid axis (or another Tune search space), or no time budget asked
        if given is not None and key not in given:
            continue  # not the user's to change: the trials keep their own
        try:
            asked = json.loads(json.dumps(asked))  # tuples read back from params.json as lists
        except TypeError:
            continue  # a Tune sampler object
        differing = sorted({shown_value(trial[key]) for trial in stored if key in trial and trial[key] != asked})
        if differing:
            changes.append(f"{key} = {', '.join(differing)}, not {shown_value(asked)}")
    if changes:
        raise InputError(
            f"--resume continues {experiment_path.name!r} as its trials were started: {'; '.join(changes)} (Tune "
            f"restores a trial with its own config and never reopens a finished one). Resume without changing "
            f"them, start a new experiment (another --out), or run in-process (--local), where --resume takes a "
            f"new time budget")


def _run_result(config: dict[str, Any], path: str, checkpoint: tune.Checkpoint | None) -> RunResult:
    """A finished trial as Tune reports it: its flat config, its folder and its latest checkpoint, read through the
    storage filesystem Tune wrote them with (copied here first from a remote one)."""
    if checkpoint is None:  # checkpoint_at_end: a finished trial always has one
        raise TrialFailed(f"the trial in {path} finished without a checkpoint")
    folder = local_copy(path, checkpoint.filesystem)  # Tune keeps a trial's checkpoints inside its folder
    within = Path(checkpoint.path).relative_to(path)
    return RunResult(config=RunConfig.build(config), path=folder, checkpoint=folder / within / CHECKPOINT_NAME)


def _check_finished(name: str, last_results: list[dict[str, Any] | None]) -> None:
    unfinished = sum(not (result or {}).get("done") for result in last_results)
    if unfinished:
        raise ExperimentInterrupted(
            f"{unfinished} of {len(last_results)} trials of {name!r} did not finish; continue them with --resume")


#: The start of a traceback's last line: ``ValueError: ...``, ``ray.exceptions.RayTaskError: ...``.
_NAMED_EXCEPTION = re.compile(r"^[\w.]*(Error|Exception|Exit|Interrupt|Failed)\w*: ")


def trial_failed(failed: int, total: int, error: BaseException | str | None, error_file: Path | None) -> TrialFailed:
    """The one-line :class:`TrialFailed` for ``failed`` of ``total`` trials, naming the first's error and log.

    Tune wraps the trial's exception in a ``RayTaskError`` (or an ``ActorDiedError`` when it was
    raised in ``setup``) whose text is the whole remote traceback; its last line, ``Type: message``
    of the exception the trial raised, is what the line shows.
    """
    cause = getattr(error, "cause", None) or error
    message = (str(cause or "").strip().splitlines() or [type(cause).__name__])[-1].strip()
    # A remote traceback ends in "ValueError: ..." already; a bare exception's text does not.
    if isinstance(cause, BaseException) and not _NAMED_EXCEPTION.match(message):
        message = f"{type(cause).__name__}: {message}"
    which = "the trial" if total == 1 else f"{failed} of {total} trials; the first"
    return TrialFailed(f"{which} failed: {message}",
                       error_file=error_file if error_file is not None and error_file.exists() else None)


@contextlib.contextmanager
def _trial_failures() -> Iterator[None]:
    """Turns ``tune.run``'s ``TuneError("Trials did not complete", trials)`` into :class:`TrialFailed`."""
    try:
        yield
    except tune.TuneError as exc:
        trials = [trial for trial in (exc.args[1] if len(exc.args) > 1 else []) if trial.status == "ERROR"]
        if not trials:
            raise TrialFailed(" ".join(str(exc).split())) from exc
        first = trials[0]
        # The copy in the experiment folder (next to the results), not the one in Ray's session folder.
        error_file = Path(first.path) / EXPR_ERROR_FILE
        raise trial_failed(len(trials), len(exc.args[1]), first.get_pickled_error() or first.get_error(),
                           error_file) from exc
