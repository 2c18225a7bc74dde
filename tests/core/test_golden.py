"""The outer loop finds exactly what it found before: every variant, two seeds, bit for bit (tests/core/golden.py)."""

from __future__ import annotations

import json

import pytest

from tests.core.golden import FIXTURE, SEEDS, fingerprint, kernel_probe

FIXTURE_DATA = json.loads(FIXTURE.read_text())
PROBE = kernel_probe()
RECORDED = FIXTURE_DATA["by_kernel_probe"]
#: The surrogate runs are the same for every probe's machines: their keys from any recorded probe.
SURROGATE_KEYS = sorted(next(iter(RECORDED.values()))["fingerprints"])


def check(key: str, expected: dict) -> None:
    variant, seed = key.split("/seed")
    assert int(seed) in SEEDS
    assert fingerprint(variant, int(seed)) == expected


@pytest.mark.parametrize("key", sorted(FIXTURE_DATA["portable"]))
def test_a_run_without_a_surrogate_finds_the_same_archive_and_metrics_on_every_machine(key):
    check(key, FIXTURE_DATA["portable"][key])


@pytest.mark.parametrize("key", SURROGATE_KEYS)
def test_a_surrogate_run_finds_the_same_archive_and_metrics_as_before(key):
    if PROBE not in RECORDED:
        recorded = ", ".join(f"{probe} ({entry['machine']})" for probe, entry in RECORDED.items())
        pytest.skip(f"no fingerprints for this machine's torch kernels (probe {PROBE}; recorded: {recorded}); "
                    f"record them from a commit known to be right with `python -m tests.core.golden`")
    check(key, RECORDED[PROBE]["fingerprints"][key])


def test_the_kernel_probe_is_stable_within_a_machine():
    assert kernel_probe() == PROBE


def test_with_portable_kernels_every_surrogate_run_matches_on_this_machine_too():
    """Under portable kernels this machine's probe has fingerprints recorded (an AMD EPYC's and an Intel Xeon's,
    which differ: docs/results/portable_kernels/README.md) and its runs match them; a machine that computes another
    probe, or other runs, fails rather than skips."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "DSAGE_RAY_KERNELS": "portable", "PYTHONPATH": str(root)}
    done = subprocess.run([sys.executable, "-m", "tests.core.golden", "--check"], cwd=root, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and "golden: all equal" in done.stdout, done.stdout + done.stderr[-2000:]
