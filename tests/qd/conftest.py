"""Fixtures for the QD tests."""

import pytest

from tests.qd.helpers import make_bitmap_archive, make_latent_archive


@pytest.fixture
def bitmap_archive():
    return make_bitmap_archive()


@pytest.fixture
def latent_archive():
    return make_latent_archive()
