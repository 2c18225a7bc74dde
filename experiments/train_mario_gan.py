"""Trains the Mario level GAN (SPEC §3) as a WGAN on every 56-wide window of the human levels.

The original DSAGE generator was a weight-clipped WGAN (RMSprop lr 5e-5) trained for 5,000 epochs;
that is out of reach on a 2-core CPU, and after a few hundred generator steps the clipped WGAN
still draws nearly empty levels. The default here is therefore WGAN-GP (gradient penalty, Adam;
Gulrajani et al. 2017), which draws ground, pipes and platforms within the 1,780 generator steps
of the shipped 50-CPU-minute run;
``--loss clip`` trains the original recipe. The critic has no BatchNorm under the gradient penalty
(the penalty is per sample) and its width is ``--critic-channels``. The generator is always the
SPEC's DCGAN. After training, the generator's BatchNorm running statistics are re-estimated over
``--bn-batches`` batches of latents, so that eval mode (which the package uses: a level depends only
on its own latent) draws the same levels as training mode.

The script stops at ``--epochs`` or ``--minutes``, whichever comes first, and records both
in the weights file's metadata. ``--minutes`` counts this process's CPU time by default
(``--clock wall`` for wall clock), so the budget means the same on a busy shared machine.
One *epoch* here is one pass of the critic over all windows
(``windows / batch`` critic steps, i.e. ``/ critic_steps`` generator steps), as in the
original training code.

Example (the shipped weights: see the README's Mario section for the exact command)::

    python experiments/train_mario_gan.py --minutes 50 --threads 1 --out dsage_ray/domains/mario/assets/generator.pt
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import json
import time
from pathlib import Path
from typing import Literal

import numpy as np
import torch
import tyro
from torch import nn

from dsage_ray.domains.mario.encoding import one_hot_levels
from dsage_ray.domains.mario.generator import Generator, save_generator, scores_to_levels
from dsage_ray.domains.mario.human_levels import human_windows
from dsage_ray.domains.mario.render import render_level
from dsage_ray.domains.mario.tiles import NUM_TILES


class Critic(nn.Module):
    """DCGAN discriminator without a sigmoid (a WGAN critic): ``(n, 17, 64, 64)`` → ``(n,)``.

    Args:
        num_tiles: Input channels, one per tile.
        base_channels: Channels of the first layer; later layers have 2×, 4×, 8× this.
        batch_norm: BatchNorm between layers (the DCGAN critic); off for WGAN-GP, whose penalty
            is defined per sample.
    """

    def __init__(self, *, num_tiles: int = NUM_TILES, base_channels: int = 64, batch_norm: bool = True) -> None:
        super().__init__()
        c = base_channels

        def down(cin: int, cout: int) -> list[nn.Module]:
            norm = [nn.BatchNorm2d(cout)] if batch_norm else []
            return [nn.Conv2d(cin, cout, 4, 2, 1, bias=not batch_norm), *norm, nn.LeakyReLU(0.2, True)]

        self.net = nn.Sequential(
            nn.Conv2d(num_tiles, c, 4, 2, 1, bias=False), nn.LeakyReLU(0.2, True),  # 32×32
            *down(c, 2 * c),  # 16×16
            *down(2 * c, 4 * c),  # 8×8
            *down(4 * c, 8 * c),  # 4×4
            nn.Conv2d(8 * c, 1, 4, 1, 0, bias=False),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x).reshape(-1)


def init_weights(module: nn.Module) -> None:
    """DCGAN initialisation: N(0, 0.02) convolutions, N(1, 0.02) BatchNorm scales."""
    if isinstance(module, (nn.Conv2d, nn.ConvTranspose2d)):
        nn.init.normal_(module.weight, 0.0, 0.02)
    elif isinstance(module, nn.BatchNorm2d):
        nn.init.normal_(module.weight, 1.0, 0.02)
        nn.init.zeros_(module.bias)


def gradient_penalty(critic: nn.Module, real: torch.Tensor, fake: torch.Tensor) -> torch.Tensor:
    """WGAN-GP: mean of ``(‖∇D(x̂)‖ − 1)²`` at random points between real and fake samples."""
    alpha = torch.rand(real.shape[0], 1, 1, 1, device=real.device)
    mixed = (alpha * real + (1 - alpha) * fake).requires_grad_(True)
    (grad,) = torch.autograd.grad(critic(mixed).sum(), mixed, create_graph=True)
    return ((grad.flatten(1).norm(dim=1) - 1) ** 2).mean()


@torch.no_grad()
def recalibrate_batch_norm(generator: nn.Module, *, batches: int, batch_size: int, device: torch.device) -> None:
    """Re-estimates BatchNorm running statistics as a plain average over fresh latent batches.

    During GAN training the running averages trail a moving generator; averaging over the final
    weights makes eval-mode levels match what the critic saw.
    """
    norms = {m: m.momentum for m in generator.modules() if isinstance(m, nn.BatchNorm2d)}
    for m in norms:
        m.reset_running_stats()
        m.momentum = None  # cumulative moving average
    generator.train()
    for _ in range(batches):
        generator(torch.randn(batch_size, generator.latent_dim, device=device))
    for m, momentum in norms.items():
        m.momentum = momentum
    generator.eval()


def tile_histogram(levels: np.ndarray) -> np.ndarray:
    return np.bincount(levels.ravel(), minlength=NUM_TILES) / levels.size


@dataclasses.dataclass
class Args:
    """The script's flags: ``--help`` prints each with the description under it."""

    out: str = "dsage_ray/domains/mario/assets/generator.pt"
    """weights file to write"""
    epochs: int = 5000
    """epochs (paper: 5000); --minutes usually stops first"""
    minutes: float = 10.0
    """training budget in minutes of --clock"""
    clock: Literal["cpu", "wall"] = "cpu"
    """what --minutes counts: this process's CPU time or wall clock"""
    batch_size: int = 32
    """windows per critic and generator batch"""
    critic_steps: int = 5
    """critic steps per generator step"""
    loss: Literal["gp", "clip"] = "gp"
    """gp: WGAN-GP with Adam; clip: the original weight-clipped WGAN with RMSprop"""
    lr: float | None = None
    """learning rate (None: 1e-4 for gp, 5e-5 for clip)"""
    clip: float = 0.01
    """weight clip (--loss clip)"""
    gp_weight: float = 10.0
    """gradient penalty weight (--loss gp)"""
    critic_channels: int = 32
    """critic width (first layer's channels)"""
    snapshot_every: int = 100
    """generator steps between snapshots written to --out (0: only at the end)"""
    bn_batches: int = 50
    """latent batches for the final BatchNorm statistics"""
    seed: int = 0
    """seed of torch and of the window order"""
    # One thread by default: on a shared 2-core machine OpenMP spin-waits burn CPU time for nothing.
    threads: int = 1
    """torch threads"""
    device: str = "cpu"
    """torch device"""
    log_dir: str = "tb_logs/mario_gan"
    """TensorBoard runs go in a timestamped subfolder"""
    log_every: int = 10
    """generator steps between scalar logs"""


def parse_args(argv: list[str] | None = None) -> Args:
    """``Args`` from the command line, with the loss's default learning rate filled in."""
    args = tyro.cli(Args, args=argv, description=__doc__.split("\n\n")[0])
    if args.lr is None:
        args = dataclasses.replace(args, lr=1e-4 if args.loss == "gp" else 5e-5)
    return args


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    device = torch.device(args.device)

    windows = human_windows()
    human_hist = tile_histogram(windows)
    n = len(windows)
    critic_steps_per_epoch = n // args.batch_size

    generator = Generator().to(device)
    critic = Critic(base_channels=args.critic_channels, batch_norm=args.loss == "clip").to(device)
    generator.apply(init_weights)
    critic.apply(init_weights)
    if args.loss == "gp":
        opt_g = torch.optim.Adam(generator.parameters(), lr=args.lr, betas=(0.5, 0.9))
        opt_c = torch.optim.Adam(critic.parameters(), lr=args.lr, betas=(0.5, 0.9))
    else:
        opt_g = torch.optim.RMSprop(generator.parameters(), lr=args.lr)
        opt_c = torch.optim.RMSprop(critic.parameters(), lr=args.lr)

    from torch.utils.tensorboard import SummaryWriter  # only the training script needs TensorBoard

    run_dir = Path(args.log_dir) / datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    writer = SummaryWriter(str(run_dir))
    fixed_z = torch.randn(16, generator.latent_dim, device=device)

    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    start, cpu_start = time.perf_counter(), time.process_time()
    deadline = clock() + 60.0 * args.minutes
    order = rng.permutation(n)
    cursor = 0
    critic_steps = gen_steps = 0
    stop_reason = "epochs"

    def snapshot(reason: str) -> dict:
        """Writes ``--out`` from a copy of the generator (BatchNorm re-estimated) and logs its samples.

        Called every ``--snapshot-every`` generator steps too, so a stopped run leaves usable weights.
        """
        model = copy.deepcopy(generator)
        recalibrate_batch_norm(model, batches=args.bn_batches, batch_size=args.batch_size, device=device)
        # Quality check in the mode the package uses it (eval: BatchNorm running statistics).
        with torch.no_grad():
            levels = scores_to_levels(model(torch.randn(512, model.latent_dim, device=device)))
            samples = scores_to_levels(model(fixed_z))
        tile_l1 = float(np.abs(tile_histogram(levels) - human_hist).sum())
        for i, level in enumerate(samples[:4]):
            writer.add_image(f"samples/{i}", render_level(level, scale=4), gen_steps, dataformats="HWC")
        writer.add_scalar("tile_histogram_l1", tile_l1, gen_steps)
        writer.flush()
        meta = {
            "epochs": critic_steps / critic_steps_per_epoch,
            "generator_steps": gen_steps,
            "critic_steps": critic_steps,
            "stop_reason": reason,
            "wall_seconds": round(time.perf_counter() - start, 1),
            "cpu_seconds": round(time.process_time() - cpu_start, 1),
            "threads": args.threads,
            "device": str(device),
            "windows": n,
            "batch_size": args.batch_size,
            "loss": args.loss,
            "lr": args.lr,
            "clip": args.clip if args.loss == "clip" else None,
            "gp_weight": args.gp_weight if args.loss == "gp" else None,
            "critic_channels": args.critic_channels,
            "tile_histogram_l1_vs_human": tile_l1,
            "trained_at": datetime.datetime.now().isoformat(timespec="seconds"),
        }
        save_generator(model, args.out, meta=meta)
        return meta

    while critic_steps < args.epochs * critic_steps_per_epoch:
        if clock() > deadline:
            stop_reason = "minutes"
            break
        # --- critic: maximise D(real) - D(fake), kept (roughly) 1-Lipschitz by the penalty or the clip.
        for _ in range(args.critic_steps):
            if cursor + args.batch_size > n:
                order, cursor = rng.permutation(n), 0
            # One-hot per batch: all windows at once would be 2 GB of float32.
            real = torch.from_numpy(one_hot_levels(windows[order[cursor:cursor + args.batch_size]])).to(device)
            cursor += args.batch_size
            with torch.no_grad():
                fake = generator(torch.randn(args.batch_size, generator.latent_dim, device=device))
            loss_c = critic(fake).mean() - critic(real).mean()
            loss = loss_c + args.gp_weight * gradient_penalty(critic, real, fake) if args.loss == "gp" else loss_c
            opt_c.zero_grad(set_to_none=True)
            loss.backward()
            opt_c.step()
            if args.loss == "clip":
                for p in critic.parameters():
                    p.data.clamp_(-args.clip, args.clip)
            critic_steps += 1
        # --- generator: maximise D(G(z)).
        loss_g = -critic(generator(torch.randn(args.batch_size, generator.latent_dim, device=device))).mean()
        opt_g.zero_grad(set_to_none=True)
        loss_g.backward()
        opt_g.step()
        gen_steps += 1
        if gen_steps % args.log_every == 0:
            epoch = critic_steps / critic_steps_per_epoch
            writer.add_scalar("loss/critic", loss_c.item(), gen_steps)
            writer.add_scalar("loss/generator", loss_g.item(), gen_steps)
            writer.add_scalar("wasserstein_estimate", -loss_c.item(), gen_steps)
            writer.add_scalar("epoch", epoch, gen_steps)
            print(f"step {gen_steps:5d} epoch {epoch:6.2f} W {-loss_c.item():+.4f} G {loss_g.item():+.4f} "
                  f"wall {time.perf_counter() - start:6.0f}s cpu {time.process_time() - cpu_start:6.0f}s", flush=True)
        if args.snapshot_every and gen_steps % args.snapshot_every == 0:
            meta = snapshot("running")
            print(f"snapshot at step {gen_steps}: tile histogram L1 vs human {meta['tile_histogram_l1_vs_human']:.3f}",
                  flush=True)

    meta = snapshot(stop_reason)
    print(json.dumps({"out": args.out, "log_dir": str(run_dir), **meta}, indent=2))
    writer.close()
    return meta


if __name__ == "__main__":
    main()
