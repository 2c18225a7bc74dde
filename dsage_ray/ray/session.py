"""The one place dsage_ray starts or joins Ray: a local cluster listens on this machine only.

Ray's services (the GCS, the raylet, every worker's gRPC server) accept tasks, and a task is code. On Linux,
Ray 2.60 binds them to every interface by default, with its token as the only guard. A cluster that dsage_ray
starts for itself (``--local`` aside, every audit and run without ``--address``) needs no other machine, so
:func:`start_ray` starts it on the loopback address: Ray's own choice on macOS and Windows
(``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER`` unset there), made here for this one start. Token authentication stays as
Ray sets it (on for a new local cluster unless ``RAY_AUTH_MODE=disabled``; the test suite disables it).

A cluster given by ``--address`` / ``RAY_ADDRESS`` is the user's: joined as it is, secured as its owner set it up
(token authentication, a private network; ``dsage_ray/ray/README.md``).
"""

from __future__ import annotations

import contextlib
import logging
import os
from typing import Any, Iterator

import ray

from dsage_ray.kernels import pin_portable_kernels

#: Ray's switch between "this machine only" (loopback, as on macOS and Windows) and "reachable by other nodes".
_CLUSTER_SWITCH = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


def start_ray(address: str | None = None, *, num_cpus: int | None = None, **init_kwargs: Any) -> None:
    """Joins the cluster at ``address`` (or ``RAY_ADDRESS``), else starts a local one bound to 127.0.0.1.

    A no-op when this process is already connected (a Tune trial, a test session's cluster).

    Args:
        address: ``"auto"``, ``"host:6379"``, ``"ray://host:10001"`` or ``None``.
        num_cpus: Logical CPUs of a *local* cluster (ignored when joining one).
        init_kwargs: Further ``ray.init`` arguments (e.g. ``log_to_driver=False``).
    """
    if ray.is_initialized():
        return
    address = address or os.environ.get("RAY_ADDRESS")
    if address:
        carried = pin_portable_kernels()  # a local cluster's workers inherit this process's environment instead
        if carried:
            init_kwargs = {**init_kwargs, "runtime_env": {"env_vars": carried}}
        ray.init(address=address, **init_kwargs)
        return
    # Ray announces the token it enabled with a suggestion to opt out; the token is wanted here (docs/TRUST.md).
    logging.getLogger("ray._private.authentication.authentication_token_setup").setLevel(logging.ERROR)
    with _loopback_only():
        ray.init(num_cpus=num_cpus, include_dashboard=False, **init_kwargs)


@contextlib.contextmanager
def _loopback_only() -> Iterator[None]:
    """Ray picks the loopback address as the node's while this is open (restored after: a later join of a remote
    cluster in this process must announce a reachable address)."""
    from ray._private import ray_constants

    saved_env, saved_flag = os.environ.get(_CLUSTER_SWITCH), ray_constants.ENABLE_RAY_CLUSTER
    # The environment reaches the processes ray.init starts (the GCS, the raylet and their agents); the constant is
    # what this process already read from it when Ray was imported.
    os.environ[_CLUSTER_SWITCH] = "0"
    ray_constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        ray_constants.ENABLE_RAY_CLUSTER = saved_flag
        if saved_env is None:
            os.environ.pop(_CLUSTER_SWITCH, None)
        else:
            os.environ[_CLUSTER_SWITCH] = saved_env
