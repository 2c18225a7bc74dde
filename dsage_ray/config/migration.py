"""Old key names that the commands in docs/results/ still use: those commands run as printed.

No release had these keys (dsage_ray is unreleased); an entry stays only where a committed record's command
needs it, so that the command that printed a table still runs. Any other key that is gone is an unknown key, and
the error names the closest current ones.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from dsage_ray.config.parsing import shown_value
from dsage_ray.config.schema import ConfigError

#: Keys moved into the ``experimental`` section (old name → new name), under their old names in the records'
#: commands (the Maze's equal-compute record and the surrogate accuracy record; docs/DECISIONS.md links both).
RENAMED_KEYS: dict[str, str] = {
    "surrogate.holdout_levels": "experimental.holdout_levels",
    "selection.screen_pool": "experimental.screen_pool",
    "selection.screen_precision": "experimental.screen_precision",
}


@dataclasses.dataclass(frozen=True)
class RemovedKey:
    """A key that is gone: the values it could hold that behave as today, and why it went."""

    accepted: tuple[Any, ...]
    why: str


_COST_MODEL = "the screen's cost model is the domain's"
#: Removed keys that a record's command sets to a value that runs as today (the screened design in the Maze's
#: equal-compute record: ``selection.cost_offset=200``; the audit_during_training record: ``image_levels=0``).
#: Such a value loads as before; any other is refused with the reason, since today's
#: code would run something else.
REMOVED_KEYS: dict[str, RemovedKey] = {
    # The screen's cost model is the domain's now (the Maze's: the mean path length plus 200).
    "selection.cost_measure": RemovedKey(("", "mean_path_length"), _COST_MODEL),
    "selection.cost_offset": RemovedKey((1.0, 200.0), _COST_MODEL),
    # A setting of how a run is carried out, not of what it computes: any value loads.
    "image_levels": RemovedKey((), "fixed (4 elite levels per image)"),
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
