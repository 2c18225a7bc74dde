"""DSAGE_RAY_KERNELS: portable kernels set the libraries' switches and make ``auto`` precision fp32."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from dsage_ray import kernels

ROOT = Path(__file__).resolve().parents[1]


def test_native_by_default_and_a_typo_is_named(monkeypatch):
    monkeypatch.delenv(kernels.SWITCH, raising=False)
    assert not kernels.portable() and kernels.pin_portable_kernels() == {}
    monkeypatch.setenv(kernels.SWITCH, "portible")
    with pytest.raises(ValueError, match="DSAGE_RAY_KERNELS='portible': expected 'portable' or 'native'"):
        kernels.portable()


def test_a_portable_process_pins_every_library_before_torch_runs_and_predicts_in_fp32():
    code = ("import dsage_ray, os, torch\n"
            "from dsage_ray.surrogate.surrogate import resolve_precision\n"
            "print(torch.backends.cpu.get_cpu_capability(), os.environ['MKL_CBWR'], torch.backends.mkldnn.enabled,"
            " resolve_precision('auto', torch.device('cpu')))")
    env = {**os.environ, kernels.SWITCH: "portable", "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert done.stdout.split() == ["AVX2", "COMPATIBLE", "False", "fp32"], done.stderr[-2000:]
