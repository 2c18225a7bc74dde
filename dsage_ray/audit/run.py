"""``run_audit``: the DSAGE search (through Ray Tune, or in this process) followed by the collection."""

from __future__ import annotations

from pathlib import Path

from dsage_ray.audit.collection import build_collection
from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain, get_domain

#: Sub-folders of an audit folder.
SEARCH_DIR, COLLECTION_DIR = "search", "collection"


def check_audit_folder(out_dir: str | Path, *, resume: bool = False, collect_only: bool = False) -> None:
    """Refuses to overwrite an audit by accident, or to continue one that is not there.

    Raises:
        ValueError: ``out_dir`` already holds an audit and neither ``resume`` nor ``collect_only`` is set,
            or one of them is set and ``out_dir`` holds no search.
    """
    out_dir = Path(out_dir)
    search = out_dir / SEARCH_DIR
    if resume or collect_only:
        if not search.is_dir():
            raise ValueError(f"{out_dir} holds no audit search ({search} is missing): nothing to "
                             f"{'resume' if resume else 'collect from'}")
    elif search.exists() or (out_dir / COLLECTION_DIR).exists():
        raise ValueError(f"{out_dir} already holds an audit: pass --resume to continue its search, --collect-only "
                         f"to rebuild its collection, or choose another --out")


def run_audit(
    config: RunConfig,
    *,
    out_dir: str | Path,
    local: bool = False,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    episodes: int | None = None,
    max_levels: int | None = None,
    collect_only: bool = False,
) -> Path:
    """Searches for failures of the config's agent and writes the collection; returns its folder.

    Everything that can be checked without Ray is checked first (the audit folder, the agents, Java for
    Mario), so bad input fails in one line before any search starts.

    Args:
        config: An audit config (:func:`dsage_ray.audit.collection.audit_config`).
        out_dir: Audit folder: the search goes to ``out_dir/search``, the collection to ``out_dir/collection``.
        local: Run the search and the re-evaluations in this process instead of through Ray.
        workers: Simulator actors (sets ``ray.num_workers``).
        address: Ray cluster to join (default ``RAY_ADDRESS`` or a new local one).
        resume: Continue an interrupted search from its last checkpoint.
        episodes: Episodes (Mario: runs) per re-evaluation in the collection (default: the config's).
        max_levels: Keep only this many of the worst elites.
        collect_only: Skip the search; build the collection from the last checkpoint of the search in
            ``out_dir`` (e.g. of an interrupted run, which ``resume`` could also continue).

    Raises:
        ValueError: An existing audit in ``out_dir`` (without ``resume``/``collect_only``), a missing one
            (with them), or an agent or simulator that cannot be used.
    """
    out_dir = Path(out_dir)
    search_dir = out_dir / SEARCH_DIR
    check_audit_folder(out_dir, resume=resume, collect_only=collect_only)
    if workers is not None:
        config = config.replace(**{"ray.num_workers": workers})
    collection_config = (config if episodes is None
                         else config.replace(**{get_domain(config.domain).audit.episodes_key: int(episodes)}))
    build_domain(config).preflight()
    if local:
        from dsage_ray.core.loop import run_locally

        if not collect_only:
            run_locally(config, out_dir=search_dir, resume=resume)
        archive = final_archive(search_dir)
        return build_collection(archive, config=collection_config, out_dir=out_dir / COLLECTION_DIR,
                                max_levels=max_levels, search_dir=search_dir)

    from dsage_ray.ray.cli import run_with_tune
    from dsage_ray.ray.pool import SimulatorPool

    if collect_only:
        experiment = search_dir / config.name
    else:
        experiment = Path(run_with_tune(config, address=address, resume=resume, out_dir=search_dir))
    archive = final_archive(experiment)
    workers = collection_config.ray.num_workers
    pool = SimulatorPool(config=collection_config) if workers > 0 else None
    try:
        return build_collection(archive, config=collection_config, out_dir=out_dir / COLLECTION_DIR,
                                evaluator=pool, workers=max(workers, 1), max_levels=max_levels,
                                search_dir=experiment)
    finally:
        if pool is not None:
            pool.close()


def final_archive(search: Path):
    """The ground-truth archive in the latest checkpoint of a search.

    Args:
        search: A ``--local`` run folder (its checkpoint file), or a Tune trial or experiment folder
            (the checkpoint file in its latest ``checkpoint_NNNNNN`` folder).

    Raises:
        CheckpointError: The search left no checkpoint, or it cannot be read.
    """
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, CheckpointError, load_checkpoint

    candidates = [search / CHECKPOINT_NAME] if (search / CHECKPOINT_NAME).is_file() else sorted(
        [*search.glob(f"checkpoint_*/{CHECKPOINT_NAME}"), *search.glob(f"*/checkpoint_*/{CHECKPOINT_NAME}")],
        key=lambda p: int(p.parent.name.rsplit("_", 1)[-1]))
    if not candidates:
        raise CheckpointError(f"{search}: the search left no checkpoint ({CHECKPOINT_NAME}) to read the archive from")
    return load_checkpoint(candidates[-1])["archive"]
