"""The default settings of the audits during training (the callbacks' and the training scripts')."""

from __future__ import annotations

from typing import Any, Mapping

#: Training iterations (RLlib) or checkpoints (Tune) between audits, by default.
DEFAULT_AUDIT_EVERY = 50
#: Real evaluations of each audit's DSAGE search, by default.
DEFAULT_AUDIT_BUDGET = 30
#: The audit's preset (its search settings; ``budget`` replaces the preset's).
DEFAULT_PRESET = "tiny"
#: Episodes per level when the suite and the new failures are re-evaluated (None: the preset's, 5 for ``tiny``).
DEFAULT_EPISODES = None
#: The series folder inside a callback's ``out_dir`` (module checkpoints go to ``out_dir/checkpoints``).
SERIES_SUBDIR = "audit_series"
#: Config keys of every audit unless the caller's ``overrides`` set them: a smaller random start and
#: selection than ``tiny`` (so that ``audit_budget`` 30 is one cold outer iteration after 20 random levels, or
#: three warm-started ones), and no pictures in the search's TensorBoard.
DEFAULT_OVERRIDES: Mapping[str, Any] = {"n_rand": 20, "selection.count": 10, "image_every": 0}
