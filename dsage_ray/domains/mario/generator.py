"""The DCGAN level generator (SPEC: Mario) and the weights shipped with the package.

A 32-d latent goes through five transposed convolutions to a 17 × 64 × 64 map; the top-left
16 × 56 crop, argmax over the 17 tile channels, is the level. The weights in
``assets/generator.pt`` were trained by ``experiments/train_mario_gan.py`` (the original
DSAGE weights are not available).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from dsage_ray.agents.loader import describe_exception
from dsage_ray.domains.mario.tiles import LEVEL_HEIGHT, LEVEL_WIDTH, NUM_TILES
from dsage_ray.errors import InputError

BUILTIN_WEIGHTS = Path(__file__).parent / "assets" / "generator.pt"


class GeneratorError(InputError, RuntimeError):
    """A generator weights file is missing, unreadable, or does not fit the architecture."""


class Generator(nn.Module):
    """DCGAN generator: latent ``(n, latent_dim)`` → non-negative tile scores ``(n, 17, 64, 64)``.

    Args:
        latent_dim: Size of the latent vector.
        num_tiles: Output channels, one per tile.
        base_channels: Channels of the last hidden layer; earlier layers have 2×, 4×, 8× this.
    """

    def __init__(self, *, latent_dim: int = 32, num_tiles: int = NUM_TILES, base_channels: int = 64) -> None:
        super().__init__()
        self.latent_dim = latent_dim
        self.num_tiles = num_tiles
        self.base_channels = base_channels
        c = base_channels

        def up(cin: int, cout: int) -> list[nn.Module]:
            # Stride-2 transposed conv doubles the side; no bias because BN follows.
            return [nn.ConvTranspose2d(cin, cout, 4, 2, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(True)]

        self.net = nn.Sequential(
            nn.ConvTranspose2d(latent_dim, 8 * c, 4, 1, 0, bias=False), nn.BatchNorm2d(8 * c), nn.ReLU(True),  # 4×4
            *up(8 * c, 4 * c),  # 8×8
            *up(4 * c, 2 * c),  # 16×16
            *up(2 * c, c),  # 32×32
            nn.ConvTranspose2d(c, num_tiles, 4, 2, 1, bias=False), nn.ReLU(True),  # 64×64
        )

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return self.net(z.reshape(z.shape[0], self.latent_dim, 1, 1))

    def config(self) -> dict[str, int]:
        return {"latent_dim": self.latent_dim, "num_tiles": self.num_tiles, "base_channels": self.base_channels}


def save_generator(generator: Generator, path: str | Path, *, meta: dict[str, Any] | None = None,
                   half: bool = True) -> None:
    """Writes a generator file: architecture, weights (fp16 by default, to keep the asset small), meta."""
    state = {k: (v.half() if half and v.is_floating_point() else v).detach().cpu()
             for k, v in generator.state_dict().items()}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    torch.save({"format": "dsage_ray.mario.generator/1", "config": generator.config(), "state_dict": state,
                "meta": dict(meta or {})}, tmp)
    tmp.replace(path)


def load_generator(spec: str | Path = "builtin", *, device: str | torch.device = "cpu") -> Generator:
    """Loads a generator in eval mode (BatchNorm uses running statistics, so a level depends
    only on its own latent, never on the rest of the batch).

    Args:
        spec: ``"builtin"`` for the shipped weights, or a path to a file written by
            :func:`save_generator`.
        device: Torch device for the module.

    Raises:
        GeneratorError: If the file is missing or not a generator file.
    """
    path = BUILTIN_WEIGHTS if str(spec) == "builtin" else Path(spec)
    if not path.is_file():
        hint = " (train one with experiments/train_mario_gan.py)" if str(spec) == "builtin" else ""
        raise GeneratorError(f"generator weights not found: {path}{hint}")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several unrelated types for corrupt files
        raise GeneratorError(f"{path}: not a readable generator file ({describe_exception(exc)})") from None
    if not isinstance(blob, dict) or blob.get("format") != "dsage_ray.mario.generator/1":
        raise GeneratorError(f"{path}: not a dsage_ray Mario generator file (missing format tag)")
    try:
        generator = Generator(**blob["config"])
        generator.load_state_dict({k: v.float() if v.is_floating_point() else v
                                   for k, v in blob["state_dict"].items()})
    except (KeyError, TypeError, RuntimeError) as exc:
        raise GeneratorError(f"{path}: weights do not fit the generator architecture: {exc}") from None
    generator.meta = blob.get("meta", {})
    return generator.to(device).eval()


def scores_to_levels(scores: torch.Tensor) -> np.ndarray:
    """Generator output ``(n, 17, 64, 64)`` → ``(n, 16, 56)`` int64 tile indices (crop, argmax)."""
    return scores[:, :, :LEVEL_HEIGHT, :LEVEL_WIDTH].argmax(dim=1).cpu().numpy().astype(np.int64)


@torch.inference_mode()
def latents_to_levels(generator: Generator, z: np.ndarray | torch.Tensor, *, batch_size: int = 256) -> np.ndarray:
    """Decodes latents ``(n, latent_dim)`` into levels ``(n, 16, 56)`` of tile indices."""
    device = next(generator.parameters()).device
    # A copy: latents often arrive as read-only views (pyribs archives, Ray object store).
    z = z.to(torch.float32) if isinstance(z, torch.Tensor) else torch.tensor(np.asarray(z), dtype=torch.float32)
    if z.ndim != 2 or z.shape[1] != generator.latent_dim:
        raise ValueError(f"latents must have shape (n, {generator.latent_dim}), got {tuple(z.shape)}")
    out = [scores_to_levels(generator(z[i:i + batch_size].to(device))) for i in range(0, len(z), batch_size)]
    return np.concatenate(out) if out else np.zeros((0, LEVEL_HEIGHT, LEVEL_WIDTH), dtype=np.int64)
