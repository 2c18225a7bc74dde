"""Portable CPU kernels: meant to give the same surrogate run for a seed on any x86-64 CPU with AVX2, at a cost; an
AMD EPYC and an Intel Xeon still differ (docs/results/portable_kernels/README.md), so today they pin a run to a kind
of CPU rather than to any one.

torch picks its CPU kernels by the machine: ATen's vectorised loops by the widest instruction set (AVX-512 or AVX2),
MKL's matrix products by the processor and its vendor, oneDNN's convolutions by the instruction set and the caches,
and ``surrogate.precision = "auto"`` takes bf16 where the CPU computes it natively. Each rounds differently, so a
surrogate trained on one machine ends with other weights than on another, and the search finds other levels a few
iterations in (the runs without a surrogate, MAP-Elites and DR, are the same everywhere).

``DSAGE_RAY_KERNELS=portable`` in the environment pins every one of them to a common denominator: ATen to AVX2,
MKL to its ``COMPATIBLE`` reproducibility branch (the one Intel documents for Intel *and* other vendors' CPUs; its
``AVX2`` branch falls back to the machine's own code on an AMD CPU, which is how a first design of this mode
differed between an Intel Xeon and an AMD EPYC), oneDNN off (torch's own convolution, on MKL, instead of JIT code
tuned to the CPU), and ``auto`` precision to fp32. It is read when :mod:`dsage_ray` is imported and set for the
whole process, before torch's first kernel runs, and Ray's workers inherit it (a cluster joined with ``--address``
gets it through the job's runtime environment). What it costs is measured in
``docs/results/portable_kernels/README.md``: an option, not the default. ``tests/core/test_golden.py`` checks it on
every machine the suite runs on.
"""

from __future__ import annotations

import os

#: The environment variable that turns portable kernels on (``portable``) or leaves torch's choice (unset).
SWITCH = "DSAGE_RAY_KERNELS"
#: What portable kernels set in the environment: ATen's dispatch and MKL's vendor-neutral reproducibility branch.
PORTABLE_ENV = {"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "COMPATIBLE"}


def portable() -> bool:
    """Whether this process runs portable kernels (``DSAGE_RAY_KERNELS=portable``)."""
    value = os.environ.get(SWITCH, "")
    if value not in ("", "portable", "native"):
        raise ValueError(f"{SWITCH}={value!r}: expected 'portable' or 'native' (or unset)")
    return value == "portable"


def pin_portable_kernels() -> dict[str, str]:
    """Sets :data:`PORTABLE_ENV` in this process's environment when :func:`portable`; returns what a Ray job must
    carry to its workers (empty when not portable)."""
    if not portable():
        return {}
    os.environ.update(PORTABLE_ENV)
    # oneDNN has no switch in the environment that torch reads; torch's flag is process-wide and set before any
    # network is built (importing torch here costs nothing a portable run would not pay anyway).
    import torch

    torch.backends.mkldnn.enabled = False
    return {SWITCH: "portable", **PORTABLE_ENV}
