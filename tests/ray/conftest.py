"""Ray test settings; the session's one cluster (``ray_session``) lives in tests/conftest.py."""

from __future__ import annotations

import os

# Must be set before Ray starts; the test machine has no token set up.
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
# Tune prints a progress table every few seconds otherwise.
os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")
