"""The public Python API: what ``from dsage_ray import ...`` gives (docs/API.md).

* :func:`run` — one DSAGE run (``dsage-ray run``) → :class:`RunResult`;
* :func:`ablate` — a grid of runs as one Tune experiment (``dsage-ray ablate``) → :class:`ExperimentResult`;
* :func:`run_audit` — search for levels where an agent fails and save them (``dsage-ray audit``) →
  :class:`Collection` of :class:`CollectionLevel`;
* :class:`RunConfig` and :func:`resolve_config` — the config a run resolves from a file, a dict or defaults;
* the errors: every one the package raises on purpose is a :class:`DsageError`, bad input an
  :class:`InputError` (a ``ValueError``).

The command line calls these same functions.
"""

from dsage_ray.audit.results import Collection, CollectionLevel
from dsage_ray.audit.run import run_audit
from dsage_ray.config import RunConfig
from dsage_ray.errors import DsageError, InputError, ResourceError, TrialFailed
from dsage_ray.results import ExperimentResult, RunResult
from dsage_ray.runs import ablate, resolve_config, run

__all__ = ["Collection", "CollectionLevel", "DsageError", "ExperimentResult", "InputError", "ResourceError",
           "RunConfig", "RunResult", "TrialFailed", "ablate", "resolve_config", "run", "run_audit"]
