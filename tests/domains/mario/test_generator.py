"""The DCGAN generator and the shipped weights."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dsage_ray.domains.mario.generator import (BUILTIN_WEIGHTS, Generator, GeneratorError, latents_to_levels,
                                               load_generator, save_generator)
from dsage_ray.domains.mario.tiles import validate_level


def test_architecture_matches_spec():
    generator = Generator(latent_dim=32)
    convs = [m for m in generator.modules() if isinstance(m, torch.nn.ConvTranspose2d)]
    assert [(c.in_channels, c.out_channels) for c in convs] == [(32, 512), (512, 256), (256, 128), (128, 64), (64, 17)]
    assert all(c.bias is None and c.kernel_size == (4, 4) for c in convs)
    out = generator.eval()(torch.randn(2, 32))
    assert out.shape == (2, 17, 64, 64) and (out >= 0).all()  # final ReLU


def test_shipped_generator_makes_valid_16x56_levels():
    generator = load_generator("builtin")
    z = np.random.default_rng(0).standard_normal((64, 32)).astype(np.float32)
    levels = latents_to_levels(generator, z)
    assert levels.shape == (64, 16, 56) and levels.dtype == np.int64
    for level in levels:
        validate_level(level)
    # Not a constant map: different latents give different levels.
    assert len({level.tobytes() for level in levels}) > 32
    assert generator.meta.get("generator_steps", 0) > 0, "the shipped weights record their training budget"


def test_levels_do_not_depend_on_the_batch():
    generator = load_generator("builtin")
    z = np.random.default_rng(1).standard_normal((8, 32)).astype(np.float32)
    together = latents_to_levels(generator, z)
    alone = np.stack([latents_to_levels(generator, z[i:i + 1])[0] for i in range(8)])
    assert (together == alone).all()


def test_save_and_load_round_trip(tmp_path):
    torch.manual_seed(0)
    generator = Generator().eval()
    path = tmp_path / "g.pt"
    save_generator(generator, path, meta={"note": "test"}, half=False)
    loaded = load_generator(path)
    z = torch.randn(4, 32)
    assert torch.equal(generator(z), loaded(z))
    assert loaded.meta == {"note": "test"} and not loaded.training


def test_bad_generator_files_give_clear_errors(tmp_path):
    with pytest.raises(GeneratorError, match="not found"):
        load_generator(tmp_path / "missing.pt")
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"this is not a torch file")
    with pytest.raises(GeneratorError, match="not a readable generator file"):
        load_generator(garbage)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    with pytest.raises(GeneratorError, match="missing format tag"):
        load_generator(other)
    wrong = tmp_path / "wrong.pt"
    save_generator(Generator(base_channels=8), wrong)
    blob = torch.load(wrong, weights_only=True)
    blob["config"]["base_channels"] = 16
    torch.save(blob, wrong)
    with pytest.raises(GeneratorError, match="do not fit"):
        load_generator(wrong)


def test_latents_must_have_the_latent_size():
    with pytest.raises(ValueError, match=r"\(n, 32\)"):
        latents_to_levels(Generator().eval(), np.zeros((2, 16)))


def test_builtin_weights_are_small():
    assert BUILTIN_WEIGHTS.stat().st_size < 8_000_000
