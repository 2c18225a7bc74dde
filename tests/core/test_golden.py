"""The outer loop finds exactly what it found before: every variant, two seeds, bit for bit (tests/core/golden.py)."""

from __future__ import annotations

import json

import pytest

from tests.core.golden import FIXTURE, SEEDS, fingerprint

EXPECTED = json.loads(FIXTURE.read_text())


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_a_seed_finds_the_same_archive_and_metrics_as_before(key):
    variant, seed = key.split("/seed")
    assert int(seed) in SEEDS
    assert fingerprint(variant, int(seed)) == EXPECTED[key]
