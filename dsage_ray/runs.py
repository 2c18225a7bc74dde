"""Running DSAGE from Python: one run (:func:`run`) or a grid of runs (:func:`ablate`).

``dsage-ray run`` and ``dsage-ray ablate`` call these with the config the command line resolved; a
script or notebook calls them with a config file, a :class:`~dsage_ray.config.RunConfig` or a dict of
dotted keys. Ray is imported only for runs that go through Tune.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal, Mapping, Sequence, Union

from dsage_ray.config import RunConfig, flatten, read_config_file, resumed_config
from dsage_ray.errors import InputError
from dsage_ray.preflight import preflight
from dsage_ray.results import ExperimentResult, RunResult

#: Where a run's config comes from: a TOML/JSON file, a built config, dotted (or nested) keys, or
#: ``None`` for the defaults.
ConfigSource = Union[str, "os.PathLike[str]", RunConfig, Mapping[str, Any], None]


def resolve_config(
    source: ConfigSource = None,
    *,
    preset: str | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> RunConfig:
    """The validated config of ``source`` with ``preset`` and ``overrides`` applied, as ``--preset``/``--set`` are.

    Args:
        source: A TOML/JSON config file, a :class:`~dsage_ray.config.RunConfig`, a dict of dotted
            (``{"surrogate.epochs": 5}``) or nested keys, or ``None`` (the defaults: the Maze, preset
            ``paper``).
        preset: A preset of the config's domain (``tiny``, ``demo``, ``cpu``, ``paper``, ...).
        overrides: Dotted keys applied last, like ``--set KEY=VALUE``.

    Raises:
        ConfigError: An unreadable file, an unknown key or preset, an invalid value; the message names it.
        InputError: A ``preset`` for a ``RunConfig`` (its preset is already applied), or a source of
            another type.
    """
    overrides = dict(overrides or {})
    if isinstance(source, RunConfig):
        if preset is not None:
            raise InputError("preset: a RunConfig has its preset applied already; pass a config file or a dict "
                             "of keys with the preset, or build the config with RunConfig.build(preset=...)")
        return source.replace(**overrides) if overrides else source
    layered = {**overrides, **({"preset": preset} if preset is not None else {})}
    if source is None:
        return RunConfig.build(layered)
    if isinstance(source, Mapping):
        return RunConfig.build({**flatten(dict(source)), **flatten(layered)})
    if isinstance(source, (str, os.PathLike)):
        return RunConfig.from_file(source, layered)
    raise InputError(f"config: expected a file path, a RunConfig or a dict of keys, got {type(source).__name__}")


def given_keys(source: ConfigSource = None, *, preset: str | None = None,
               overrides: Mapping[str, Any] | None = None) -> set[str] | None:
    """The dotted keys a config source, ``preset`` and ``overrides`` set explicitly (as :func:`resolve_config`
    reads them); None for a :class:`~dsage_ray.config.RunConfig`, whose every key counts as given."""
    if isinstance(source, RunConfig):
        return None
    given = set(flatten(dict(overrides or {})))
    if preset is not None:
        given.add("preset")
    if isinstance(source, Mapping):
        given |= set(flatten(dict(source)))
    elif isinstance(source, (str, os.PathLike)):
        given |= set(read_config_file(source))
    return given


def _config_and_given_keys(source: ConfigSource, *, preset: str | None, overrides: Mapping[str, Any] | None,
                           workers: int | None, resume: bool) -> tuple[RunConfig, set[str] | None]:
    """The config of ``run``/``ablate`` (``workers`` sets ``ray.num_workers``) and, for a resume, the keys
    given (:func:`given_keys`, with ``ray.num_workers`` when ``workers`` is set); None when not resuming."""
    given = given_keys(source, preset=preset, overrides=overrides) if resume else None
    config = resolve_config(source, preset=preset, overrides=overrides)
    if workers is not None:
        config = config.replace(**{"ray.num_workers": workers})
        given = None if given is None else given | {"ray.num_workers"}
    return config, given


def _stored_config(config: RunConfig, *, local: bool, out: str | os.PathLike[str] | None) -> RunConfig | None:
    """The config of the run a resume of ``config`` continues: its local checkpoint's, or the latest checkpoint's
    of its Tune trial; None when there is none (the resume then fails as it would have)."""
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, checkpoint_config, latest_tune_checkpoint
    from dsage_ray.ray.storage import local_folder

    if local:
        found: Path | None = (Path(out) if out is not None else Path("tb_logs") / config.name) / CHECKPOINT_NAME
        found = found if found.is_file() else None
    else:
        storage = local_folder(out if out is not None else "tb_logs")
        if storage is None:  # a remote storage URI: Tune restores the trials with the configs they began with
            return None
        found = latest_tune_checkpoint(storage / config.name, "*")
    return checkpoint_config(found) if found is not None else None


def run(
    config: ConfigSource = None,
    *,
    preset: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    local: bool = False,
    out: str | os.PathLike[str] | None = None,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    max_failures: int = 2,
) -> RunResult:
    """Runs DSAGE (or the baseline its ``variant`` names) to its budget: ``dsage-ray run`` from Python.

    The agents and simulators are checked before anything starts
    (:func:`~dsage_ray.preflight.preflight`), so an agent that does not load fails at once.

    Args:
        config: The config source (:func:`resolve_config`): a TOML/JSON file, a ``RunConfig``, or a
            dict of dotted keys.
        preset: A preset of the config's domain (``tiny``, ``demo``, ``cpu``, ``paper``).
        overrides: Dotted config keys applied last (``{"budget": 300}``), like ``--set``.
        local: Run in this process without Ray (same archive for the same seed as through Tune).
        out: ``local``: the run folder (default ``tb_logs/<name>``). Through Tune: the storage folder
            (default ``tb_logs``), or a storage URI (``file://``, ``s3://``: :mod:`dsage_ray.ray.storage`); the
            run folder is then ``out/<name>/<trial>``.
        workers: Simulator actors (sets ``ray.num_workers``; ignored by ``local`` runs).
        address: A Ray cluster to join (default: ``RAY_ADDRESS``, else a new local cluster).
        resume: Continue the run in ``out`` from its last checkpoint, with the config it began with: a key given
            here (in a config file, ``preset`` or ``overrides``) must be the one it began with (but
            ``time_budget``), a default that changed since is left as it was. A ``RunConfig`` counts as
            given whole.
        max_failures: Through Tune: restores of a crashed trial from its last checkpoint.

    Returns:
        The run's folder, checkpoint, metrics and final archive.

    Raises:
        InputError: A bad config, agent or ``out`` (e.g. holding a run without ``resume``).
        ResourceError: The trial does not fit the machine or cluster (``workers`` too high).
        TrialFailed: The Tune trial failed more than ``max_failures`` times.
    """
    config, given = _config_and_given_keys(config, preset=preset, overrides=overrides, workers=workers,
                                           resume=resume)
    if given is not None:
        # A run resumes as it began: only the keys given now may differ from its checkpoint's (and are refused
        # there, but for time_budget), not a default that changed since.
        stored = _stored_config(config, local=local, out=out)
        config = config if stored is None else resumed_config(config, stored, given=given)
    preflight(config)
    if local:
        from dsage_ray.core.checkpoint import CHECKPOINT_NAME
        from dsage_ray.core.loop import run_locally

        run_dir = run_locally(config, out_dir=Path(out) if out is not None else Path("tb_logs") / config.name,
                              resume=resume)
        return RunResult(config=config, path=run_dir, checkpoint=run_dir / CHECKPOINT_NAME)
    from dsage_ray.ray.launch import run_with_tune

    return run_with_tune(config, address=address, resume=resume, out_dir=out if out is not None else "tb_logs",
                         max_failures=max_failures)


def ablate(
    config: ConfigSource = None,
    *,
    preset: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    grid: Sequence[str] = (),
    seeds: int | Sequence[int] | None = None,
    variants: Sequence[str] | None = None,
    out: str | os.PathLike[str] = "tb_logs",
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    api: Literal["tuner", "run"] = "tuner",
    max_failures: int = 2,
) -> ExperimentResult:
    """Runs a grid of DSAGE runs as one Ray Tune experiment: ``dsage-ray ablate`` from Python.

    Every grid point's config is validated, and its agents loaded, before Ray starts.

    Args:
        config, preset, overrides: The base config, as in :func:`run`.
        grid: ``"KEY=V1,V2"`` axes over any config key (``"surrogate.epochs=50,200"``,
            ``"variant=dsage,map_elites"``, ``"seed=0,1,2"``).
        seeds: How many seeds (``0..K-1``) or which (default 5, unless ``grid`` names ``seed``).
        variants: The variants to compare (default: the domain's paper comparison when ``grid``
            names nothing else, else the config's variant).
        out: Storage folder; the experiment is ``out/<name>``.
        workers: Simulator actors per trial (``ray.num_workers``).
        address, max_failures: As in :func:`run`.
        resume: Continue the interrupted experiment in ``out``. Tune restores each trial with its own config:
            a key given here (a config file's, ``preset``, ``overrides``, ``workers``) that differs from the
            trials' is refused, a default that changed since is left as it was. A ``RunConfig`` counts as
            given whole.
        api: Tune's entry point: ``"tuner"`` (``tune.Tuner``) or ``"run"`` (``tune.run``).

    Returns:
        The experiment folder and one :class:`~dsage_ray.results.RunResult` per trial.
    """
    config, given = _config_and_given_keys(config, preset=preset, overrides=overrides, workers=workers,
                                           resume=resume)
    from dsage_ray.ray.launch import ablate as ablate_with_tune

    return ablate_with_tune(config, grid=grid, seeds=seeds, variants=variants, address=address, resume=resume,
                            out_dir=out, api=api, max_failures=max_failures, given=given)
