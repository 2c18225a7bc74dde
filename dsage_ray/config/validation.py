"""The rules a run config's values must keep: each names its key and says why a value is impossible."""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path
from typing import Any, Literal

from dsage_ray.config.parsing import dotted_value, field_types, not_a_choice
from dsage_ray.config.schema import ConfigError, MutatingEmitter
from dsage_ray.domains.registry import CheckedSection, get_domain
from dsage_ray.errors import InputError


def validate(config: Any) -> None:
    """Raises :class:`ConfigError` naming the first key of ``config`` (a :class:`~dsage_ray.config.RunConfig`)
    with an impossible value."""
    def need(cond: bool, key: str, why: str) -> None:
        if not cond:
            raise ConfigError(f"{key}: {why} (got {dotted_value(config, key)!r})")

    check_choices(config)
    try:
        get_domain(config.domain)
    except InputError as exc:
        raise ConfigError(f"domain: {exc}") from None
    for name, section in config.sections.items():
        check_choices(section, f"{name}.")
    # The name is a folder under tb_logs/ (or --out): it may not climb out of it.
    need(bool(config.name) and not Path(config.name).is_absolute() and ".." not in Path(config.name).parts, "name",
         "must be a relative folder name without '..' (runs are written under tb_logs/ or --out)")
    need(config.budget >= 1, "budget", "must be positive")
    need(config.time_budget >= 0, "time_budget", "must be >= 0 seconds (0: no limit)")
    need(config.n_rand >= 1, "n_rand", "must be positive")
    need(config.budget >= config.n_rand or not config.uses_surrogate, "budget",
         f"must be at least n_rand={config.n_rand} (the first outer iteration evaluates n_rand solutions)")
    need(config.image_every >= 0, "image_every", "must be >= 0 (0: no images)")
    need(config.torch_threads >= 1, "torch_threads", "must be positive")
    for key in ("epochs", "batch_size", "train_window", "channels"):
        need(getattr(config.surrogate, key) >= 1, f"surrogate.{key}", "must be positive")
    need(config.surrogate.lr > 0, "surrogate.lr", "must be positive")
    need(config.surrogate.occupancy_weight >= 0, "surrogate.occupancy_weight", "must be >= 0")
    need(config.experimental.holdout_levels >= 0, "experimental.holdout_levels", "must be >= 0 (0: off)")
    need(not config.surrogate.init or config.uses_surrogate, "surrogate.init",
         "a warm start needs a surrogate (this variant runs without one)")
    need(not config.surrogate.occupancy_sum_measure or config.surrogate.kind != "one_stage",
         "surrogate.occupancy_sum_measure", "needs the two-stage surrogate (only it predicts occupancy)")
    measure_names = getattr(config.sections[config.domain], "measures", None)
    need(not config.surrogate.occupancy_sum_measure or measure_names is None
         or config.surrogate.occupancy_sum_measure in measure_names, "surrogate.occupancy_sum_measure",
         f"{config.surrogate.occupancy_sum_measure!r} is not one of the measures {list(measure_names or [])}")
    need(not config.surrogate.prior_measure or measure_names is None
         or config.surrogate.prior_measure in measure_names, "surrogate.prior_measure",
         f"{config.surrogate.prior_measure!r} is not one of the measures {list(measure_names or [])}")
    for key in ("num_emitters", "batch_size", "exploit_iterations", "mutation_cells"):
        need(getattr(config.qd, key) >= 1, f"qd.{key}", "must be positive")
    need(config.qd.sigma0 > 0, "qd.sigma0", "must be positive")
    need(config.selection.count >= 1, "selection.count", "must be positive")
    need(config.uses_surrogate or not config.pipeline, "pipeline",
         "pipelines the surrogate's phases with the evaluations; this variant has no surrogate")
    if config.search == "auto":
        need(config.uses_surrogate, "search", f"auto starts as DSAGE; variant {config.variant!r} has no surrogate")
        need(bool(get_domain(config.domain).direct_search), "search",
             f"auto needs the domain's direct search; domain {config.domain!r} declares none")
        need(not config.pipeline, "search", "auto reads the surrogate's cost from an iteration that did not overlap "
                                          "the evaluations; set pipeline = false")
        need(not config.surrogate.init, "search", "auto compares the surrogate's levels with the random first "
                                                "ones, which a warm start (surrogate.init) skips")
    need(config.selection.elite_mutants >= 0, "selection.elite_mutants", "must be >= 0 (0: none)")
    need(config.uses_surrogate or not config.selection.elite_mutants, "selection.elite_mutants",
         "adds mutants to a surrogate's picks; this variant's QD search mutates its elites already")
    need(config.mutates_elites or not config.selection.elite_mutants, "selection.elite_mutants",
         f"mutates with qd.emitter's operator; {config.qd.emitter!r} has none (use "
         f"{' or '.join(typing.get_args(MutatingEmitter))})")
    need(0.0 < config.experimental.elite_share <= 1.0, "experimental.elite_share", "must be in (0, 1]")
    need(config.experimental.mutant_sigma >= 0.0, "experimental.mutant_sigma", "must be >= 0 (0: qd.sigma0)")
    need(not config.experimental.mutant_sigma or config.qd.emitter != "map_elites", "experimental.mutant_sigma",
         "is the Gaussian step of continuous mutants; qd.emitter 'map_elites' mutates bitmaps (qd.mutation_cells)")
    need(config.experimental.mutant_parents == "elites" or not config.selection.elite_mutants
         or not (config.surrogate.init and config.experimental.init_prior), "experimental.mutant_parents",
         "'evaluated' draws parents among the run's evaluated levels, and a warm start's prior levels "
         "(experimental.init_prior) come without their solutions; set experimental.init_prior = false")
    need(config.selection.screen_episodes >= 0, "selection.screen_episodes", "must be >= 0 (0: no screen)")
    # The screening keys apply only to a domain that can screen (types.ScreenableDomain), which its registration
    # declares: the check imports no domain.
    need(get_domain(config.domain).screenable or not config.selection.screen_episodes, "selection.screen_episodes",
         f"screens levels with the domain's cheap estimate; domain {config.domain!r} has none (set 0)")
    need(config.uses_surrogate or config.qd.emitter == "map_elites" or not config.selection.screen_episodes,
         "selection.screen_episodes", f"screens a surrogate's picks, or MAP-Elites' mutants; qd.emitter "
         f"{config.qd.emitter!r} without a surrogate adapts to every level it asked for")
    need(config.experimental.screen_pool >= 1, "experimental.screen_pool",
         "must be >= 1 (candidates screened per pick)")
    need(config.selection.screen_episodes > 0 or not config.selection.screen_gain, "selection.screen_gain",
         "ranks screened candidates; set selection.screen_episodes > 0 to screen, or screen_gain = false")
    need(config.experimental.gain_window >= 1, "experimental.gain_window", "must be positive")
    need(config.experimental.gain_neighbours >= 1, "experimental.gain_neighbours", "must be positive")
    need(config.ray.num_workers >= 0, "ray.num_workers", "must be >= 0")
    need(config.ray.cpus_per_worker > 0, "ray.cpus_per_worker", "must be positive")
    need(config.ray.trial_cpus > 0, "ray.trial_cpus", "must be positive")
    need(config.experimental.chunk_size >= 0, "experimental.chunk_size", "must be >= 0 (0: automatic)")
    dom = config.domain_config
    prefix = config.domain
    need(len(dom.measures) >= 1, f"{prefix}.measures", "needs at least one measure")
    need(len(dom.archive_dims) == len(dom.measures), f"{prefix}.archive_dims",
         f"needs one entry per measure ({len(dom.measures)})")
    need(all(d >= 1 for d in dom.archive_dims), f"{prefix}.archive_dims", "cells per measure must be positive")
    if dom.measure_ranges:
        need(len(dom.measure_ranges) == len(dom.measures), f"{prefix}.measure_ranges",
             f"needs one (low, high) pair per measure ({len(dom.measures)})")
        need(all(len(r) == 2 and r[0] < r[1] for r in dom.measure_ranges), f"{prefix}.measure_ranges",
             "each range must be (low, high) with low < high")
    need(len(config.selection.block) == len(dom.measures), "selection.block",
         f"needs one block size per measure ({len(dom.measures)})")
    need(all(b >= 1 for b in config.selection.block), "selection.block", "block sizes must be positive")
    if isinstance(dom, CheckedSection):
        dom.validate(lambda cond, key, why: need(cond, f"{prefix}.{key}", why))


def check_choices(config: Any, prefix: str = "") -> None:
    """Every ``Literal``-typed field holds one of its names (also when set as an attribute, not built)."""
    for name, annotation in field_types(type(config)).items():
        value = getattr(config, name)
        if dataclasses.is_dataclass(annotation):
            check_choices(value, f"{prefix}{name}.")
        elif typing.get_origin(annotation) is Literal and value not in typing.get_args(annotation):
            raise ConfigError(not_a_choice(prefix + name, value, typing.get_args(annotation)))
