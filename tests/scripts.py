"""Importing a script of ``experiments/`` or ``benchmarks/`` as a module in a test."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest


def import_script(path: Path, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """``path`` imported under its stem, kept in ``sys.modules`` for the test (tyro resolves annotations there)."""
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
    return module
