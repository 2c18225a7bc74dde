"""The gym domain's input error, in a module of its own so that the space's parts can all raise it."""

from __future__ import annotations

from dsage_ray.errors import InputError


class SpaceError(InputError):
    """A space file or ``--param`` string that does not describe a parameter space; the message says where."""
