"""Surrogate speed: inner-loop predictions/s against the machine's conv throughput, and one training epoch.

(1) Predictions/s of the two-stage Maze model (5×16×16 one-hot) through ``Surrogate.predict`` at the
    inner-loop batch size, next to a plain stack of bare 64→64 3×3 convolutions on the same 16×16 grid
    with the same FLOPs per sample, timed in the same run. Their ratio says how close the model runs
    to what the convolution kernels can do here: ≥ 0.8 means the arithmetic, not Python or the
    framework, is the bottleneck. A large reference convolution gives the machine's peak for context.
(2) Wall time of one training epoch on N Maze samples at batch 64.

Timings take the best of several interleaved repeats, because the machine is shared and other
processes only ever make a repeat slower.

Usage: python benchmarks/bench_surrogate.py [--threads 2] [--batch 150] [--train-samples 2000]
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Callable

import numpy as np
import torch
from torch import nn

from dsage_ray.config import SurrogateConfig
from dsage_ray.surrogate import Surrogate
from dsage_ray.types import EvaluationResult

CHANNELS, SIZE, NUM_MEASURES = 5, 16, 2


def maze_levels(n: int, seed: int = 0) -> np.ndarray:
    tiles = np.random.default_rng(seed).integers(0, CHANNELS, size=(n, SIZE, SIZE))
    return np.eye(CHANNELS, dtype=np.float32)[tiles].transpose(0, 3, 1, 2).copy()


def flops_per_sample(model: nn.Module, x: torch.Tensor) -> float:
    """Multiply-adds ×2 of every Conv2d and Linear in one forward pass, divided by the batch size."""
    total = 0

    def hook(module: nn.Module, inputs: tuple[torch.Tensor, ...], output: torch.Tensor) -> None:
        nonlocal total
        if isinstance(module, nn.Conv2d):
            kh, kw = module.kernel_size
            total += 2 * output.numel() * (module.in_channels // module.groups) * kh * kw
        else:
            total += 2 * output.numel() * module.in_features

    handles = [m.register_forward_hook(hook) for m in model.modules() if isinstance(m, (nn.Conv2d, nn.Linear))]
    with torch.inference_mode():
        model.eval()(x)
    for handle in handles:
        handle.remove()
    return total / len(x)


def best_time(fn: Callable[[], object], *, calls: int) -> float:
    """Seconds per call: the fastest of ``calls`` calls after one warm-up call."""
    fn()
    best = float("inf")
    for _ in range(calls):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def conv_stack(layers: int) -> Callable[[torch.Tensor], torch.Tensor]:
    convs = [nn.Conv2d(64, 64, kernel_size=3, padding=1, bias=False).eval() for _ in range(layers)]

    def run(x: torch.Tensor) -> torch.Tensor:
        with torch.inference_mode():
            for conv in convs:
                x = conv(x)
        return x

    return run


def bench_inference(*, batch: int, repeats: int, calls: int) -> None:
    config = SurrogateConfig(device="cpu", predict_batch_size=max(batch, 1))
    surrogate = Surrogate(kind="two_stage", input_channels=CHANNELS, input_shape=(SIZE, SIZE),
                          occupancy_shape=(SIZE, SIZE), num_measures=NUM_MEASURES, config=config, seed=0)
    levels = maze_levels(batch)
    model_flops = flops_per_sample(surrogate.model, torch.from_numpy(levels))

    # The reference does the same arithmetic per sample as bare 64->64 3x3 convs (the model's bulk).
    per_layer = 2 * SIZE * SIZE * 64 * 64 * 9
    layers = max(1, round(model_flops / per_layer))
    stack, stack_input = conv_stack(layers), torch.rand(batch, 64, SIZE, SIZE)
    big_conv = nn.Conv2d(256, 256, kernel_size=3, padding=1, bias=False).eval()
    big_input = torch.rand(16, 256, 32, 32)
    big_flops = 2 * big_input[:, :1].numel() * 256 * 256 * 9

    model_s, stack_s, big_s = [], [], []
    for _ in range(repeats):  # interleaved, so that load from other processes hits all three alike
        model_s.append(best_time(lambda: surrogate.predict(levels), calls=calls))
        stack_s.append(best_time(lambda: stack(stack_input), calls=calls))
        with torch.inference_mode():
            big_s.append(best_time(lambda: big_conv(big_input), calls=max(1, calls // 4)))
    model_gflops = model_flops * batch / min(model_s) / 1e9
    stack_gflops = layers * per_layer * batch / min(stack_s) / 1e9
    big_gflops = big_flops / min(big_s) / 1e9

    print(f"model: {model_flops / 1e6:.1f} MFLOP per prediction (two-stage, Maze {CHANNELS}x{SIZE}x{SIZE})")
    print(f"surrogate predictions/s at batch {batch}: {batch / min(model_s):,.0f} "
          f"({min(model_s) * 1e3:.1f} ms per batch, {model_gflops:.1f} GFLOP/s)")
    print(f"plain conv stack ({layers} x 64->64 3x3 on {SIZE}x{SIZE}, same FLOPs/sample): {stack_gflops:.1f} GFLOP/s "
          f"= {batch / min(stack_s):,.0f} samples/s")
    print(f"large reference conv (256->256 3x3, 16x32x32): {big_gflops:.1f} GFLOP/s")
    print(f"ratio model / plain conv stack: {model_gflops / stack_gflops:.2f}  "
          f"(>= 0.8: the convolutions, not Python, are the bottleneck)")
    print(f"ratio model / large reference conv: {model_gflops / big_gflops:.2f}")


def bench_training(*, samples: int, batch_size: int, epochs: int) -> None:
    config = SurrogateConfig(device="cpu", epochs=1, batch_size=batch_size)
    surrogate = Surrogate(kind="two_stage", input_channels=CHANNELS, input_shape=(SIZE, SIZE),
                          occupancy_shape=(SIZE, SIZE), num_measures=NUM_MEASURES, config=config, seed=0)
    levels = maze_levels(samples)
    rng = np.random.default_rng(0)
    results = [EvaluationResult(objective=1.0, measures=rng.random(NUM_MEASURES),
                                occupancy=rng.random((SIZE, SIZE), dtype=np.float32)) for _ in range(samples)]
    dataset = surrogate.make_dataset()
    dataset.append(encoded=levels, results=results)
    times = []
    for _ in range(epochs):
        start = time.perf_counter()
        surrogate.train(dataset)
        times.append(time.perf_counter() - start)
    print(f"training: one epoch on {samples} Maze samples at batch {batch_size}: best {min(times):.2f} s, "
          f"median {float(np.median(times)):.2f} s over {epochs} epochs "
          f"({samples / min(times):,.0f} samples/s)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--batch", type=int, default=150, help="inner-loop batch (5 emitters x 30)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--calls", type=int, default=20)
    parser.add_argument("--train-samples", type=int, default=2000)
    parser.add_argument("--train-batch", type=int, default=64)
    parser.add_argument("--train-epochs", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    # Other processes on the cores make multi-threaded small convolutions much slower (threads wait on
    # each other at every op): read the numbers against the load average.
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, mkldnn {torch.backends.mkldnn.is_available()}, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    bench_inference(batch=args.batch, repeats=args.repeats, calls=args.calls)
    bench_training(samples=args.train_samples, batch_size=args.train_batch, epochs=args.train_epochs)


if __name__ == "__main__":
    main()
