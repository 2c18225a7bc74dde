"""Portable CPU kernels: meant to give the same surrogate run for a seed on any x86-64 CPU with AVX2, at a cost.

torch picks its CPU kernels by the machine: ATen's vectorised loops by the widest instruction set (AVX-512 or AVX2),
MKL's matrix products and oneDNN's convolutions by the processor, and ``surrogate.precision = "auto"`` takes bf16
where the CPU computes it natively. Each rounds differently, so a surrogate trained on an AVX-512 machine ends with
other weights than on an AVX2 one, and the search finds other levels a few iterations in (the runs without a
surrogate, MAP-Elites and DR, are the same everywhere).

``DSAGE_RAY_KERNELS=portable`` in the environment pins every one of them to a common denominator: ATen and oneDNN
to AVX2, MKL to its conditional-numerical-reproducibility mode for AVX2 (``MKL_CBWR``), and ``auto`` precision
to fp32. It is read when :mod:`dsage_ray` is imported and set for the whole process, before torch's first kernel
runs, and Ray's workers inherit it (a cluster joined with ``--address`` gets it through the job's runtime
environment). Measured on the 2-core development machine (AVX-512 with native bf16, maze ``demo`` preset, 150
evaluations, ``--local``): 42.1 s against 25.0 s, so it is an option, not the default
(``docs/results/portable_kernels/README.md``). Seen on one CPU so far; ``tests/core/test_golden.py`` checks it on
every machine the suite runs on.
"""

from __future__ import annotations

import os

#: The environment variable that turns portable kernels on (``portable``) or leaves torch's choice (unset).
SWITCH = "DSAGE_RAY_KERNELS"
#: What portable kernels set: ATen's dispatch, MKL's reproducibility mode and oneDNN's widest instruction set.
PORTABLE_ENV = {"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "AVX2", "DNNL_MAX_CPU_ISA": "AVX2"}


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
    return {SWITCH: "portable", **PORTABLE_ENV}
