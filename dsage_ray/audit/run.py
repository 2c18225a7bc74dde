"""An audit end to end: the DSAGE search (through Ray Tune, or in this process), then the collection.

:func:`run_audit` is ``dsage-ray audit`` from Python (``dsage_ray.run_audit``); :func:`search_and_collect`
does the same for a config built with :func:`~dsage_ray.audit.collection.audit_config`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

from dsage_ray.audit.collection import agent_slug, audit_config, audit_spec, build_collection
from dsage_ray.audit.nominal import NOMINAL_FILE, audit_nominal, check_expect_return, play_nominal
from dsage_ray.audit.results import Collection
from dsage_ray.config import RunConfig, presets
from dsage_ray.domains.registry import DEFAULT_DOMAIN
from dsage_ray.errors import InputError
from dsage_ray.io import folder_lock, recover_replaced_dir
from dsage_ray.results import RunResult

#: Sub-folders of an audit folder.
SEARCH_DIR, COLLECTION_DIR = "search", "collection"
#: The preset of an audit of a named agent, and of one of the domain's default agent (the shipped demo
#: agent): a few minutes, so that ``dsage-ray audit`` alone is a demo, not a 2,000-evaluation search.
AGENT_PRESET, DEMO_PRESET = "cpu", "demo"


def default_preset(domain: str, *, agent: str | None) -> str:
    """The preset of an audit that names none: ``cpu`` for a named agent, else the domain's ``demo``.

    A domain without that preset falls back to ``tiny``, then to ``paper`` (which every domain has).
    """
    known = presets(domain)
    wanted = AGENT_PRESET if agent else DEMO_PRESET
    return next(name for name in (wanted, "tiny", "paper") if name in known)


def run_audit(
    *,
    agent: str | None = None,
    domain: str = DEFAULT_DOMAIN,
    reference: str | None = None,
    preset: str | None = None,
    variant: str = "dsage",
    objective: str | None = None,
    measures: Sequence[str] | None = None,
    budget: int | None = None,
    seed: int = 0,
    overrides: Mapping[str, Any] | None = None,
    out: str | os.PathLike[str] | None = None,
    local: bool = False,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    episodes: int | None = None,
    max_levels: int | None = None,
    collect_only: bool = False,
    expect_return: float | None = None,
    allow_failing_nominal: bool = False,
) -> Collection:
    """Searches for levels where ``agent`` fails and saves them reproducibly: ``dsage-ray audit`` from Python.

    Everything that can be checked before the search is (the arguments, the audit folder, the agents,
    Java for Mario), so bad input fails in one line before any search starts.

    Args:
        agent: The agent spec (``dcd:PATH``, ``rllib:PATH``, ``torchscript:PATH``, ``builtin:random``,
            ...; Mario ``astar[:ITERATIONS]``). Default: the domain's shipped demo agent
            (Maze ``rllib:ppo_maze``), with the ``demo`` preset unless ``preset`` is given.
        domain: A domain that declares audits (``maze``, ``mario``, a plug-in's).
        reference: Maze: search where ``agent`` does worse than this agent, on the same seeds.
        preset: The domain's preset (default :func:`default_preset`: ``cpu`` for a named agent).
        variant: The search: ``dsage`` or another variant of the domain (``map_elites``, ``dr``).
        objective: What the search maximises (default: the domain's first audit objective, or
            ``regression`` with a reference).
        measures: Measure names (default: the domain's audit measures).
        budget: Real evaluations of the search (default: the preset's).
        seed: The run seed; also seeds the collection's re-evaluations.
        overrides: Further dotted config keys, like ``--set``.
        out: The audit folder (default ``tb_logs/audit-<agent>-<time>``): the search goes to
            ``out/search``, the collection to ``out/collection``.
        local: Search and re-evaluate in this process instead of through Ray.
        workers: Simulator actors (sets ``ray.num_workers``).
        address: A Ray cluster to join (default ``RAY_ADDRESS`` or a new local one).
        resume: Continue the interrupted search in ``out``.
        episodes: Episodes (Mario: runs) per re-evaluation in the collection (default: the config's).
        max_levels: Keep only this many of the worst levels.
        collect_only: Skip the search; build the collection from the last checkpoint of the search in ``out``.
        expect_return: The return the agent reaches on the domain's nominal level, over its own
            ``expected_return`` (an RL Zoo folder's ``evaluations.npz``). Before the search the agent plays that
            level (:mod:`dsage_ray.audit.nominal`), and the audit stops where it does far worse than this, or,
            with no figure known, never succeeds there.
        allow_failing_nominal: Go on after a failing nominal check (printing it).

    Returns:
        The collection (levels worst first, their seeds and numbers, the summary, the report's path).

    Raises:
        InputError: Bad arguments, an agent that does not load, an ``out`` that already holds an audit
            (without ``resume``/``collect_only``) or holds none (with them).
        NominalCheckFailed: The agent does far worse on the nominal level than expected, or never succeeds
            there (an :class:`InputError`; nothing is searched or written).
        ResourceError: The search's trial does not fit the machine.
        TrialFailed: The Tune trial of the search failed.
    """
    for name, value in (("episodes", episodes), ("max_levels", max_levels), ("budget", budget)):
        if value is not None and value < 1:
            raise InputError(f"{name} must be positive, got {value}")
    if workers is not None and workers < 0:
        raise InputError(f"workers must be >= 0 (0: simulate in the trial process), got {workers}")
    if collect_only and out is None:
        raise InputError("collect_only needs the out folder of the search to collect from")
    check_expect_return(expect_return)
    spec = audit_spec(domain)  # an unknown domain, or one without audits, before its presets are read
    started = _started(out) if resume or collect_only else None
    config = audit_config(domain=domain, agent=agent, reference=reference,
                          preset=preset or default_preset(domain, agent=agent), variant=variant,
                          objective=objective, measures=measures, budget=budget, seed=seed,
                          overrides=dict(overrides or {}), started=started)
    if (overrides or {}).get("search") == "auto" and config.search == "fixed":
        print(f"search auto: {domain} audits keep DSAGE: {spec.audit.auto_keeps_dsage}")
    if out is None:
        out = default_audit_folder(agent, domain=domain)
    return search_and_collect(config, out_dir=out, local=local, workers=workers, address=address, resume=resume,
                              episodes=episodes, max_levels=max_levels, collect_only=collect_only,
                              expect_return=expect_return, allow_failing_nominal=allow_failing_nominal)


def default_audit_folder(agent: str | None, *, domain: str = DEFAULT_DOMAIN) -> Path:
    """``tb_logs/audit-<agent>-<time>``: where an audit without ``out`` writes (the domain's demo agent without
    ``agent``)."""
    slug = agent_slug(agent or audit_spec(domain).audit.default_agent)
    return Path("tb_logs") / f"audit-{slug}-{time.strftime('%Y%m%d-%H%M%S')}"


def _started(out: str | Path | None) -> RunConfig | None:
    """The config of the search an audit folder holds, or None when it holds none to continue yet."""
    from dsage_ray.core.checkpoint import CheckpointError

    if out is None or not (Path(out) / SEARCH_DIR).is_dir():
        return None  # check_audit_folder names the problem
    try:
        return search_on_disk(Path(out) / SEARCH_DIR).config
    except CheckpointError:
        return None  # no checkpoint yet: the search starts afresh


def check_audit_folder(out_dir: str | Path, *, resume: bool = False, collect_only: bool = False) -> None:
    """Refuses to overwrite an audit by accident, or to continue one that is not there.

    Raises:
        InputError: ``out_dir`` already holds an audit and neither ``resume`` nor ``collect_only`` is set,
            or one of them is set and ``out_dir`` holds no search.
    """
    out_dir = Path(out_dir)
    search = out_dir / SEARCH_DIR
    if resume or collect_only:
        if not search.is_dir():
            raise InputError(f"{out_dir} holds no audit search ({search} is missing): nothing to "
                             f"{'resume' if resume else 'collect from'}")
    elif search.exists() or (out_dir / COLLECTION_DIR).exists():
        raise InputError(f"{out_dir} already holds an audit: pass --resume to continue its search, --collect-only "
                         f"to rebuild its collection, or choose another --out")


def search_and_collect(
    config: RunConfig,
    *,
    out_dir: str | os.PathLike[str],
    local: bool = False,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    episodes: int | None = None,
    max_levels: int | None = None,
    collect_only: bool = False,
    expect_return: float | None = None,
    allow_failing_nominal: bool = False,
) -> Collection:
    """The audit of an audit config: the search (:func:`dsage_ray.run`), then :func:`build_collection`.

    Args:
        config: An audit config (:func:`~dsage_ray.audit.collection.audit_config`).
        out_dir, local, workers, address, resume, episodes, max_levels, collect_only, expect_return,
            allow_failing_nominal: As in :func:`run_audit`.

    Raises:
        As :func:`run_audit`.
    """
    out_dir = Path(out_dir)
    check_expect_return(expect_return)
    check_audit_folder(out_dir, resume=resume, collect_only=collect_only)
    with folder_lock(out_dir, what="audit"):  # also: an --out that cannot be written fails before the search
        recover_replaced_dir(out_dir / COLLECTION_DIR)  # what an audit killed while writing its collection left
        return _search_and_collect(config, out_dir=out_dir, local=local, workers=workers, address=address,
                                   resume=resume, episodes=episodes, max_levels=max_levels, collect_only=collect_only,
                                   expect_return=expect_return, allow_failing_nominal=allow_failing_nominal)


def _search_and_collect(config: RunConfig, *, out_dir: Path, local: bool, workers: int | None, address: str | None,
                        resume: bool, episodes: int | None, max_levels: int | None, collect_only: bool,
                        expect_return: float | None, allow_failing_nominal: bool) -> Collection:
    from dsage_ray.domains import get_domain
    from dsage_ray.preflight import preflight
    from dsage_ray.runs import run

    search_dir = out_dir / SEARCH_DIR
    if workers is not None:
        config = config.replace(**{"ray.num_workers": workers})
    collection_config = (config if episodes is None
                         else config.replace(**{get_domain(config.domain).audit.episodes_key: int(episodes)}))
    if collect_only or episodes is not None:  # the collection's own episodes are checked before the search
        preflight(collection_config)
    if resume or collect_only:
        _check_search_loads(search_dir)  # a damaged or forged checkpoint is named before the agent plays anything
    played_now = not ((resume or collect_only) and (out_dir / NOMINAL_FILE).is_file())
    nominal = audit_nominal(lambda: _play_nominal(config, expect_return=expect_return), folder=out_dir,
                            reuse=resume or collect_only, allow_failing=allow_failing_nominal)
    if collect_only:
        search = search_on_disk(search_dir, config=config)
    else:
        try:
            search = run(config, local=local, out=search_dir, address=address, resume=resume)
        except BaseException:
            if nominal is not None and played_now and not search_dir.exists():
                # Stopped before the search began (a preflight error): leave the folder as it was.
                (out_dir / NOMINAL_FILE).unlink(missing_ok=True)
            raise
    record = None if nominal is None else nominal.to_dict()
    collection_dir = out_dir / COLLECTION_DIR
    if local or collection_config.ray.num_workers == 0:
        build_collection(search.archive, config=collection_config, out_dir=collection_dir, max_levels=max_levels,
                         search_dir=search.path, nominal=record)
        return Collection.load(collection_dir)

    from dsage_ray.ray.pool import SimulatorPool
    from dsage_ray.ray.session import start_ray

    start_ray(address)  # already connected unless collect_only
    pool = SimulatorPool(config=collection_config)
    try:
        build_collection(search.archive, config=collection_config, out_dir=collection_dir, evaluator=pool,
                         max_levels=max_levels, search_dir=search.path, nominal=record)
    finally:
        pool.close()
    return Collection.load(collection_dir)


def _check_search_loads(search_dir: Path) -> None:
    """Reads the state of the checkpoint ``search_dir`` holds, if any (CheckpointError where it does not load)."""
    from dsage_ray.core.checkpoint import CheckpointError, load_checkpoint

    try:
        checkpoint = search_on_disk(search_dir).checkpoint
    except CheckpointError:
        return  # no checkpoint yet: a resume starts afresh, a collection names what is missing
    load_checkpoint(checkpoint)


def _play_nominal(config: RunConfig, *, expect_return: float | None):
    """The nominal check of ``config``'s agent (None for a domain without a nominal level), after the preflight, so
    that an agent that does not load fails with the preflight's line."""
    from dsage_ray.preflight import preflight

    domain, = preflight(config)  # the preflight's domain: its agent is loaded once
    return play_nominal(domain, run_seed=config.seed, expect_return=expect_return)


def search_on_disk(search_dir: Path, *, config: RunConfig | None = None) -> RunResult:
    """The search an earlier audit left in ``search_dir``, for ``collect_only`` and ``resume`` (the one folder
    reader).

    A finished search is returned by :func:`dsage_ray.run`; this reads what an interrupted or earlier
    one left: the checkpoint file of a ``local`` search, or the latest ``checkpoint_NNNNNN`` folder of
    the Tune trial in ``search_dir/<name>/<trial>``.

    Args:
        search_dir: The ``search`` folder of an audit.
        config: The config to report (default: the one its checkpoint holds).

    Raises:
        CheckpointError: The search left no checkpoint, or (without ``config``) one that does not load.
    """
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, CheckpointError, checkpoint_config, latest_tune_checkpoint

    local = search_dir / CHECKPOINT_NAME
    in_tune = latest_tune_checkpoint(search_dir, "*/*")
    if local.is_file():
        run_dir, checkpoint = search_dir, local
    elif in_tune is not None:
        run_dir, checkpoint = in_tune.parent.parent, in_tune
    else:
        raise CheckpointError(f"{search_dir}: the search left no checkpoint ({CHECKPOINT_NAME}) to read the "
                              f"archive from")
    return RunResult(config=config or checkpoint_config(checkpoint), path=run_dir, checkpoint=checkpoint)
