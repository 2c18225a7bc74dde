"""Installs the test agent plug-in (tests/fixtures/agent_plugin) as a real package, for the plug-in tests.

The package is a wheel written here (a zip with the module and its ``dist-info``: no build backend and
no network needed) and installed with pip into a folder of its own (``pip install --target``), never into the
running environment: the suite leaves the environment as it found it (a user's own install of a package of
that name stays). Entry points are read through ``importlib.metadata`` from ``sys.path``, so a process that has
the folder on its path (this one, via :func:`on_path`; Ray's workers, via ``PYTHONPATH``) finds the plug-in's
entry point as it would a user's package.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import importlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Iterator

#: Distribution and module of the test plug-in, and the agent kind it provides.
DIST_NAME, MODULE, KIND = "dsage-ray-test-agent-plugin", "dsage_ray_test_agent_plugin", "constant_test"
VERSION = "0.1"
SOURCE = Path(__file__).resolve().parent / "fixtures" / "agent_plugin" / f"{MODULE}.py"


def build_wheel(folder: Path) -> Path:
    """Writes the plug-in's wheel into ``folder`` and returns its path."""
    dist_info = f"{MODULE}-{VERSION}.dist-info"
    files = {
        f"{MODULE}.py": SOURCE.read_bytes(),
        f"{dist_info}/METADATA": f"Metadata-Version: 2.1\nName: {DIST_NAME}\nVersion: {VERSION}\n".encode(),
        f"{dist_info}/WHEEL": b"Wheel-Version: 1.0\nGenerator: dsage_ray tests\nRoot-Is-Purelib: true\n"
                              b"Tag: py3-none-any\n",
        f"{dist_info}/entry_points.txt": f"[dsage_ray.agents]\n{KIND} = {MODULE}:load_constant_agent\n".encode(),
    }
    record = [f"{name},sha256={_digest(data)},{len(data)}" for name, data in files.items()]
    files[f"{dist_info}/RECORD"] = ("\n".join([*record, f"{dist_info}/RECORD,,"]) + "\n").encode()
    wheel = folder / f"{MODULE}-{VERSION}-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return wheel


def pip(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args], check=True,
                   capture_output=True, timeout=300)


def install(folder: Path) -> Path:
    """Installs the plug-in into ``folder/site`` and returns that folder; nothing outside it changes."""
    site = folder / "site"
    pip("install", "--no-deps", "--no-index", "--no-cache-dir", "--target", str(site), str(build_wheel(folder)))
    return site


@contextlib.contextmanager
def on_path(site: Path) -> Iterator[None]:
    """This process finds the plug-in in ``site`` while the block runs, and forgets it after."""
    # First, as PYTHONPATH puts it for Ray's workers: the tests load this copy even where the environment has
    # a package of the same name (the folder holds nothing else, so it shadows nothing more).
    sys.path.insert(0, str(site))
    importlib.invalidate_caches()  # the entry-point scan and the import read the new folder
    try:
        yield
    finally:
        sys.path.remove(str(site))
        sys.modules.pop(MODULE, None)
        importlib.invalidate_caches()


def python_path(site: Path) -> str:
    """``PYTHONPATH`` for a process that should find the plug-in: ``site`` first, then this one's own."""
    return os.pathsep.join([str(site), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))])


def _digest(data: bytes) -> str:
    return base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
