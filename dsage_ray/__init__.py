"""dsage_ray: DSAGE on Ray, to search for diverse levels where a trained agent fails.

    import dsage_ray

    collection = dsage_ray.run_audit(agent="builtin:random", preset="tiny", local=True, out="tb_logs/api_audit")
    result = dsage_ray.run("experiments/configs/maze_dsage.toml", preset="tiny", local=True)

The public names (:mod:`dsage_ray.api`, docs/API.md) load on first use, so importing the package, or
any of its modules (a Ray simulator actor does), imports no simulator, no torch and no Ray.
"""

from __future__ import annotations

import importlib
from importlib import metadata
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dsage_ray.api import (Collection, CollectionLevel, DsageError, ExperimentResult, InputError, ResourceError,
                               RunConfig, RunResult, TrialFailed, ablate, resolve_config, run, run_audit)
    from dsage_ray.audit.series import AuditSeries
    from dsage_ray.core.warm_start import pretrain_surrogate

from dsage_ray.kernels import pin_portable_kernels

# Before torch runs a kernel in this process (DSAGE_RAY_KERNELS=portable: one run for a seed on any AVX2 CPU).
pin_portable_kernels()

try:
    __version__ = metadata.version("dsage_ray")
except metadata.PackageNotFoundError:  # a source checkout that was never installed
    __version__ = "0+unknown"

__all__ = ["AuditSeries", "Collection", "CollectionLevel", "DsageError", "ExperimentResult", "InputError",
           "ResourceError", "RunConfig", "RunResult", "TrialFailed", "__version__", "ablate", "pretrain_surrogate",
           "resolve_config", "run", "run_audit"]


#: Public names that live outside :mod:`dsage_ray.api`, by module.
_ELSEWHERE = {"AuditSeries": "dsage_ray.audit.series", "pretrain_surrogate": "dsage_ray.core.warm_start"}


def __getattr__(name: str) -> Any:
    # PEP 562: the API module (and what it imports) loads when a public name is first read.
    if name in __all__:
        return getattr(importlib.import_module(_ELSEWHERE.get(name, "dsage_ray.api")), name)
    raise AttributeError(f"module 'dsage_ray' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
