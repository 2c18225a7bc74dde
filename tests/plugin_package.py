"""Installs the test agent plug-in (tests/fixtures/agent_plugin) as a real package, for the plug-in tests.

The package is a wheel written here (a zip with the module and its ``dist-info``: no build backend and
no network needed) and installed with pip into the running environment, so that every process of it,
Ray's actors included, finds its entry point as it would a user's package. It is uninstalled afterwards.
"""

from __future__ import annotations

import base64
import hashlib
import importlib
import subprocess
import sys
import zipfile
from pathlib import Path

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


def install(folder: Path) -> None:
    pip("install", "--no-deps", "--no-index", "--no-cache-dir", str(build_wheel(folder)))
    importlib.invalidate_caches()  # this process looks for the new module and metadata afresh


def uninstall() -> None:
    pip("uninstall", "-y", DIST_NAME)
    importlib.invalidate_caches()
    sys.modules.pop(MODULE, None)


def _digest(data: bytes) -> str:
    return base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
