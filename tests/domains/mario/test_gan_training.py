"""The GAN training script's pieces (``experiments/train_mario_gan.py``) and a seconds-long run of it."""

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from dsage_ray.domains.mario.generator import Generator, latents_to_levels, load_generator

REPO_ROOT = Path(__file__).resolve().parents[3]
SCRIPT = REPO_ROOT / "experiments" / "train_mario_gan.py"


@pytest.fixture(scope="module")
def gan_script():
    spec = importlib.util.spec_from_file_location("train_mario_gan", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass resolves string annotations through sys.modules
    spec.loader.exec_module(module)
    yield module
    del sys.modules[spec.name]


class LinearCritic(nn.Module):
    def __init__(self, weight: torch.Tensor) -> None:
        super().__init__()
        self.weight = nn.Parameter(weight)

    def forward(self, x):
        return (x * self.weight).flatten(1).sum(1)


@pytest.mark.parametrize("scale", [0.5, 1.0, 3.0])
def test_gradient_penalty_of_a_linear_critic_is_its_norm_gap(gan_script, scale):
    """D(x) = <w, x> has gradient w everywhere, so the penalty is exactly (|w| - 1)²."""
    torch.manual_seed(0)
    w = torch.randn(17, 8, 8)
    w = w / w.norm() * scale
    penalty = gan_script.gradient_penalty(LinearCritic(w), torch.rand(4, 17, 8, 8), torch.rand(4, 17, 8, 8))
    assert penalty.item() == pytest.approx((scale - 1.0) ** 2, abs=1e-5)


def test_gradient_penalty_reaches_the_critic_weights(gan_script):
    critic = gan_script.Critic(base_channels=8, batch_norm=False)
    penalty = gan_script.gradient_penalty(critic, torch.rand(2, 17, 64, 64), torch.rand(2, 17, 64, 64))
    penalty.backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in critic.parameters())


def test_batch_norm_recalibration_makes_eval_mode_match_training_mode(gan_script):
    torch.manual_seed(0)
    generator = Generator(base_channels=8)
    for m in generator.modules():  # running statistics that do not describe this generator
        if isinstance(m, nn.BatchNorm2d):
            m.running_mean.fill_(5.0)
            m.running_var.fill_(0.01)
    z = torch.randn(256, generator.latent_dim)
    with torch.no_grad():
        train_levels = generator.train()(z)[:, :, :16, :56].argmax(1)
        stale = generator.eval()(z)[:, :, :16, :56].argmax(1)
    gan_script.recalibrate_batch_norm(generator, batches=20, batch_size=256, device=torch.device("cpu"))
    assert not generator.training
    with torch.no_grad():
        fresh = generator(z)[:, :, :16, :56].argmax(1)
    assert (stale == train_levels).float().mean() < 0.5
    assert (fresh == train_levels).float().mean() > 0.9


def test_a_seconds_long_training_run_writes_a_loadable_generator(tmp_path):
    out = tmp_path / "generator.pt"
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--minutes", "0.02", "--out", str(out), "--log-dir", str(tmp_path / "tb"),
         "--bn-batches", "2", "--batch-size", "8", "--critic-channels", "8"],
        capture_output=True, text=True, timeout=600, cwd=REPO_ROOT)
    assert result.returncode == 0, result.stderr[-2000:]
    generator = load_generator(out)
    meta = generator.meta
    assert meta["loss"] == "gp" and meta["generator_steps"] >= 1 and meta["stop_reason"] == "minutes"
    assert json.loads(result.stdout[result.stdout.index("{"):])["out"] == str(out)
    levels = latents_to_levels(generator, np.zeros((2, generator.latent_dim)))
    assert levels.shape == (2, 16, 56)
    assert list((tmp_path / "tb").glob("*/events.out.tfevents.*"))
