"""Fingerprints of small runs of every Maze variant on :class:`~tests.fakes.BitmapDomain`.

``tests/core/test_golden.py`` checks that the outer loop still produces exactly these: the same archive
(cells, objectives, solutions) and the same per-iteration metrics, bit for bit, so a refactor of the
loop cannot change what a seed finds. After a change that is *meant* to change results, rewrite this
machine's fingerprints with ``python -m tests.core.golden`` and say why in the commit.

A surrogate variant's run depends on how torch's CPU kernels round (AVX-512 or AVX2 code paths, native
bf16 or not): on another CPU it finds other elites a few iterations in. Its fingerprints are therefore kept
per **kernel probe** (:func:`kernel_probe`, a digest of one small training step), and a machine whose probe
has none skips them with a message saying how to record them. The variants without a surrogate (MAP-Elites,
DR) compute nothing in torch and are checked on every machine. With portable kernels (:mod:`dsage_ray.kernels`,
``DSAGE_RAY_KERNELS=portable``) the probe is meant to be one for every x86-64 machine with AVX2, so its
fingerprints are checked everywhere, in a subprocess (the mode is set when a process starts). Where that check
fails, the portable kernels are not portable to the machine: fix the kernels (as MKL's branch was, 2026-12-02), do
not record a second portable probe.
"""

from __future__ import annotations

import hashlib
import json
import platform
from pathlib import Path

import numpy as np

from dsage_ray.config import RunConfig, variants
from dsage_ray.core.runner import DSAGE, torch_threads
from tests.fakes import SMALL_RUN, BitmapDomain

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "golden_runs.json"
SEEDS = (0, 1)


def config_of(variant: str, seed: int) -> RunConfig:
    return RunConfig.build({**SMALL_RUN, "variant": variant, "seed": seed})


def fingerprint(variant: str, seed: int) -> dict[str, object]:
    """Runs ``variant`` with ``seed`` to its budget; the digest of its archive and its untimed metrics."""
    runner = DSAGE(config=config_of(variant, seed), domain=BitmapDomain())
    with torch_threads(1):
        runner.run()
    data = runner.archive.data()
    order = np.argsort(data["index"])
    archive = hashlib.sha256()
    for key in ("index", "objective", "measures", "solution"):
        archive.update(np.ascontiguousarray(np.asarray(data[key])[order]).tobytes())
    untimed = [{key: value for key, value in row.items() if "time" not in key} for row in runner.history]
    return {"archive_sha256": archive.hexdigest(), "elites": int(len(order)),
            "qd_score": [row["qd_score"] for row in runner.history],
            "metrics_sha256": hashlib.sha256(json.dumps(untimed, sort_keys=True).encode()).hexdigest()}


def kernel_probe() -> str:
    """Digest of a convolution network's forward pass, loss gradient and Adam step, in fp32 and under the
    surrogate's prediction precision (``auto``): equal on machines whose torch kernels round alike."""
    import torch

    from dsage_ray.surrogate.surrogate import resolve_precision

    with torch_threads(1):
        generator = torch.Generator().manual_seed(0)
        net = torch.nn.Sequential(torch.nn.Conv2d(3, 16, 3, padding=1), torch.nn.ReLU(),
                                  torch.nn.Conv2d(16, 16, 3, padding=1), torch.nn.ReLU(), torch.nn.Flatten(),
                                  torch.nn.Linear(16 * 8 * 8, 4))
        with torch.no_grad():
            for parameter in net.parameters():
                parameter.copy_(torch.randn(parameter.shape, generator=generator) * 0.1)
        inputs = torch.randn(32, 3, 8, 8, generator=generator)
        optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)
        loss = net(inputs).square().mean()
        loss.backward()
        optimizer.step()
        bf16 = resolve_precision("auto", torch.device("cpu")) == "bf16"
        with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            prediction = net(inputs).float()
    digest = hashlib.sha256()
    for tensor in (loss.detach(), prediction, *(p.detach() for p in net.parameters())):
        digest.update(tensor.numpy().tobytes())
    return digest.hexdigest()[:16]


def surrogate_free(key: str) -> bool:
    """Whether the run named ``variant/seedN`` computes nothing in torch (same on every machine)."""
    variant, seed = key.split("/seed")
    return not config_of(variant, int(seed)).uses_surrogate


def cpu_model() -> str:
    """The CPU's model name (Linux), else the architecture: for the reader of the fixture only."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def all_fingerprints() -> dict[str, dict[str, object]]:
    return {f"{variant}/seed{seed}": fingerprint(variant, seed) for variant in variants("maze") for seed in SEEDS}


def record(fingerprints: dict[str, dict[str, object]], fixture: dict, probe: str) -> dict:
    """``fixture`` with ``fingerprints`` split into the portable runs and this probe's surrogate runs."""
    portable = {k: v for k, v in fingerprints.items() if surrogate_free(k)}
    per_probe = {k: v for k, v in fingerprints.items() if not surrogate_free(k)}
    import torch

    from dsage_ray.surrogate.surrogate import native_cpu_bf16

    from dsage_ray import kernels

    machine = (f"{cpu_model()}, native bf16 {'yes' if native_cpu_bf16() else 'no'}, torch {torch.__version__}"
               + (", portable kernels (DSAGE_RAY_KERNELS=portable)" if kernels.portable() else ""))
    return {"portable": portable,
            "by_kernel_probe": {**fixture.get("by_kernel_probe", {}), probe: {"machine": machine,
                                                                              "fingerprints": per_probe}}}


def check_recorded() -> list[str]:
    """This machine's fingerprints against the recorded ones of its kernel probe: the keys that differ (all of them,
    with a note, when the probe has none)."""
    recorded = json.loads(FIXTURE.read_text())["by_kernel_probe"].get(kernel_probe())
    if recorded is None:
        return [f"no fingerprints recorded for kernel probe {kernel_probe()}"]
    differing = []
    for key, expected in sorted(recorded["fingerprints"].items()):
        variant, seed = key.split("/seed")
        if fingerprint(variant, int(seed)) != expected:
            differing.append(key)
    return differing


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["--check"]:  # exit 1 naming what differs (tests/core/test_golden.py, portable kernels)
        differing = check_recorded()
        print("golden:", "all equal" if not differing else "differ: " + ", ".join(differing))
        sys.exit(1 if differing else 0)
    existing = json.loads(FIXTURE.read_text()) if FIXTURE.is_file() else {}
    probe = kernel_probe()
    FIXTURE.write_text(json.dumps(record(all_fingerprints(), existing, probe), indent=1, sort_keys=True) + "\n")
    print(f"wrote {FIXTURE} (portable runs, and the surrogate runs of kernel probe {probe})")
