"""The cost of portable kernels (``DSAGE_RAY_KERNELS=portable``, :mod:`dsage_ray.kernels`) on a real run.

    python benchmarks/bench_portable_kernels.py [--budget 150] [--repeats 2]

Runs the same Maze DSAGE run (``demo`` preset, ``--local``, seed 0) in fresh processes under four settings,
alternating them ``--repeats`` times, and prints each one's median wall time and its ratio to torch's own kernels:

* ``native``: torch's choice (AVX-512 and bf16 prediction where the CPU has them);
* ``native fp32``: the same with ``surrogate.precision = fp32`` (the precision part of the cost);
* ``aten avx2``: fp32, and only ATen's vectorised loops pinned to AVX2;
* ``avx2 pins``: the first design of portable kernels (ATen and oneDNN at AVX2, MKL's ``AVX2`` branch, fp32), which
  an Intel Xeon and an AMD EPYC ran differently;
* ``portable``: ``DSAGE_RAY_KERNELS=portable`` (ATen at AVX2, MKL's ``COMPATIBLE`` branch, oneDNN off, fp32).

Target (issue 46): portable kernels become the default if they cost at most 10% of a run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = {
    "native": ({}, []),
    "native fp32": ({}, ["--set", "surrogate.precision=fp32"]),
    "aten avx2": ({"ATEN_CPU_CAPABILITY": "avx2"}, ["--set", "surrogate.precision=fp32"]),
    "avx2 pins": ({"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "AVX2", "DNNL_MAX_CPU_ISA": "AVX2"},
                  ["--set", "surrogate.precision=fp32"]),
    "portable": ({"DSAGE_RAY_KERNELS": "portable"}, []),
}


def timed_run(env: dict[str, str], extra: list[str], budget: int) -> float:
    out = Path(tempfile.mkdtemp(prefix="bench_kernels_")) / "run"
    command = [str(Path(sys.executable).with_name("dsage-ray")), "run", "experiments/configs/maze_dsage.toml",
               "--preset", "demo", "--local", "--set", f"budget={budget}", *extra, "--out", str(out)]
    started = time.perf_counter()
    subprocess.run(command, cwd=ROOT, env={**os.environ, **env}, check=True, capture_output=True)
    seconds = time.perf_counter() - started
    shutil.rmtree(out.parent)
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=int, default=150)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    times: dict[str, list[float]] = {name: [] for name in SETTINGS}
    for _ in range(args.repeats):
        for name, (env, extra) in SETTINGS.items():
            times[name].append(timed_run(env, extra, args.budget))
    native = statistics.median(times["native"])
    print(f"{'setting':<12} {'median s':>9} {'ratio':>6}  runs")
    for name, runs in times.items():
        median = statistics.median(runs)
        print(f"{name:<12} {median:>9.1f} {median / native:>6.2f}  {', '.join(f'{t:.1f}' for t in runs)}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
