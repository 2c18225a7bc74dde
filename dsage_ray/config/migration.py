"""Keys renamed or removed since they were first written: a config file, ``--set`` or a stored run naming one
still loads where today's code runs it as it was."""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from dsage_ray.config.parsing import shown_value
from dsage_ray.config.schema import ConfigError

#: Keys moved into the ``experimental`` section (old name → new name). A config file, ``--set`` or a stored
#: run naming the old key still works.
RENAMED_KEYS: dict[str, str] = {
    "surrogate.holdout_levels": "experimental.holdout_levels",
    "surrogate.init_prior": "experimental.init_prior",
    "selection.elite_share": "experimental.elite_share",
    "selection.screen_pool": "experimental.screen_pool",
    "selection.screen_precision": "experimental.screen_precision",
    "selection.gain_window": "experimental.gain_window",
    "selection.gain_neighbours": "experimental.gain_neighbours",
    "ray.chunk_size": "experimental.chunk_size",
}


@dataclasses.dataclass(frozen=True)
class RemovedKey:
    """A key that is gone: the values it could hold that behave as today, and why it went."""

    accepted: tuple[Any, ...]
    why: str


_NOT_HELPING = "measured not to help"
#: Removed keys. A stored run (or a file) holding an accepted value loads as before; any other value is refused
#: with the reason, since today's code would run something else.
REMOVED_KEYS: dict[str, RemovedKey] = {
    "selection.expected_gain": RemovedKey((False,), f"{_NOT_HELPING} (docs/DECISIONS.md)"),
    "selection.min_gain": RemovedKey((0.0,), f"{_NOT_HELPING}: expected_gain's threshold"),
    "selection.prefer_new_cells": RemovedKey((False,), f"{_NOT_HELPING} (docs/DECISIONS.md)"),
    "selection.skip_filled": RemovedKey((False,), f"{_NOT_HELPING}: the dsage_novel variant was level with dsage "
                                                  "(docs/results/maze_cpu_accel)"),
    "surrogate.init_first_picks": RemovedKey((0,), f"{_NOT_HELPING} (docs/results/audit_during_training)"),
    "surrogate.target_scaling": RemovedKey(("none",), f"{_NOT_HELPING} (surrogate_accuracy, gym_audit)"),
    "surrogate.validation_fraction": RemovedKey((0.0,), f"{_NOT_HELPING}: early stopping (surrogate_accuracy)"),
    "surrogate.patience": RemovedKey((5,), f"{_NOT_HELPING}: early stopping (surrogate_accuracy)"),
    "surrogate.dilations": RemovedKey(([1, 1], (1, 1)), f"{_NOT_HELPING} (surrogate_accuracy)"),
    "surrogate.betas": RemovedKey(([0.9, 0.999], (0.9, 0.999)), "Adam's betas are the paper's, fixed"),
    "qd.ranker": RemovedKey(("2imp",), "CMA-ME's ranker is the paper's two-stage improvement ranker, fixed"),
    "qd.initial_random_batches": RemovedKey((4,), "MAP-Elites starts with the paper's 4 random batches, fixed: 1 and "
                                                  "2 were no better (docs/DECISIONS.md)"),
    "surrogate.incremental_epochs": RemovedKey((0,), "every training runs surrogate.epochs; shorter later trainings "
                                                     "were never measured to help"),
    # The screen's cost model is the domain's now (the Maze's: the mean path length plus 200).
    "selection.cost_measure": RemovedKey(("", "mean_path_length"), "the screen's cost model is the domain's"),
    "selection.cost_offset": RemovedKey((1.0, 200.0), "the screen's cost model is the domain's"),
    # Settings of how a run is carried out, not of what it computes: any value loads.
    "surrogate.predict_batch_size": RemovedKey((), "fixed (4,096 levels per prediction chunk)"),
    "ray.placement_timeout_s": RemovedKey((), "fixed (120 s)"),
    "image_levels": RemovedKey((), "fixed (4 elite levels per image)"),
    "checkpoint_every": RemovedKey((), "a run checkpoints every outer iteration"),
}


def upgrade_keys(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted keys with renamed keys under their new names and removed keys dropped.

    Raises:
        ConfigError: A removed key holds a value today's code cannot run as it was (the message says why it went).
    """
    upgraded: dict[str, Any] = {}
    for key, value in flat.items():
        removed = REMOVED_KEYS.get(key)
        if removed is None:
            upgraded[RENAMED_KEYS.get(key, key)] = value
        elif removed.accepted and value not in removed.accepted:
            raise ConfigError(f"{key}: this key was removed ({removed.why}); only {shown_value(removed.accepted[0])} "
                              "is what runs now (docs/CONFIG.md)")
    return upgraded
