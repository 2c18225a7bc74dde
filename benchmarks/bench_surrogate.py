"""Surrogate speed: inner-loop predictions/s against the machine's conv throughput, and one training epoch.

(1) Predictions/s of the two-stage Maze model (5×16×16 one-hot) through ``Surrogate.predict`` at the
    inner-loop batch size, next to a plain stack of bare 64→64 3×3 convolutions on the same 16×16 grid
    with the same FLOPs per sample, timed in the same run. Their ratio says how close the model runs
    to what the convolution kernels can do here: ≥ 0.8 means the arithmetic, not Python or the
    framework, is the bottleneck. A large reference convolution gives the machine's peak for context.
(2) bf16 against fp32 prediction (``surrogate.precision``) on a surrogate trained here on real Maze
    evaluations (random valid levels of every wall density, run by ``--agent``): the share of unseen levels
    that both precisions put in the same cell of the Maze archive (its dims and ranges: 256×162), and the
    throughput of the same surrogate at the same batch (the inner loop's), timed interleaved in one run,
    on 1 thread (a Maze trial's default) and on ``--threads``.
(3) Wall time of one training epoch on N Maze samples at batch 64.
(4) With ``--run RUN_FOLDER`` (a finished Maze surrogate run): the same agreement for the surrogate that run
    trained (its checkpoint), on its held-out levels and on mutations of its archive's elites (what the
    inner loop predicts), next to that surrogate's own error on the held-out levels. A level changes cell
    when the bf16 difference crosses a cell boundary, so the share that moves is about mean |bf16 - fp32|
    divided by the cell width (1 wall, 4 steps of path length).

(5) With ``--setting NAME:key=value,...`` (repeatable; the syntax of ``bench_surrogate_training.py``, keys
    on top of the Maze ``cpu`` preset): cost and accuracy of each setting in ONE table, instead of (1)-(4).
    Cost, timed interleaved across the settings on ``--threads`` (the runs' torch_threads is 1): FLOPs per
    prediction, predictions/s of ``Surrogate.predict`` at the inner-loop batch (the setting's precision),
    training seconds per epoch over ``--train-samples`` levels (the cpu window) at the setting's batch size.
    With ``--run RUN_FOLDER`` also accuracy: ``bench_surrogate_training.py``'s replay of that run's data
    with ``--seeds`` initialisations per setting, summarised over its outer iterations as training seconds
    per outer iteration, the held-out Spearman ρ and the selected-batch MAE of the last measure, each a
    mean ± standard error over the seeds.

Timings take the best of several interleaved repeats, because the machine is shared and other
processes only ever make a repeat slower.

Usage: python benchmarks/bench_surrogate.py [--threads 2] [--batch 150] [--train-samples 2000]
       [--agent builtin:wall_follower] [--episodes 1] [--fit-levels 500] [--agree-levels 1000] [--run RUN_FOLDER]
       python benchmarks/bench_surrogate.py --setting paper: --setting c16:channels=16 [--run RUN_FOLDER --seeds 3]
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Callable

import numpy as np
import torch
from torch import nn

from dsage_ray.config import QDConfig, SurrogateConfig
from dsage_ray.domains.maze.domain import MazeDomain
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.plugin import MazeConfig
from dsage_ray.qd.archives import make_archive
from dsage_ray.surrogate import Surrogate
from dsage_ray.surrogate import surrogate as surrogate_module
from dsage_ray.surrogate.surrogate import native_cpu_bf16
from dsage_ray.surrogate.models import pad_to_power_of_two
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
    surrogate_module.PREDICT_BATCH_SIZE = max(batch, 1)  # one chunk per timed call
    config = SurrogateConfig(device="cpu", precision="fp32")
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


def bench_precision(*, batch: int, repeats: int, calls: int, threads: list[int], agent: str, episodes: int,
                    fit_levels: int, heldout_levels: int, agree_levels: int, fit_epochs: int) -> None:
    domain = MazeDomain(config=MazeConfig(agent=agent, episodes=episodes))
    # Wall densities up to 0.9 spread the levels over the archive's whole wall axis, as the inner loop does.
    levels = random_valid_levels(fit_levels + heldout_levels + agree_levels, seed=0, density_range=(0.0, 0.9))
    solutions = np.stack([level.walls.reshape(-1) for level in levels]).astype(domain.solution_dtype)
    encoded = pad_to_power_of_two(domain.encode(solutions), domain.encoding_pad_channel)
    fit, heldout, agree = np.split(encoded, [fit_levels, fit_levels + heldout_levels])
    start = time.perf_counter()
    results = [domain.evaluate(solution, seed=i) for i, solution in enumerate(solutions[:fit_levels + heldout_levels])]
    evaluate_s = time.perf_counter() - start
    surrogate_module.PREDICT_BATCH_SIZE = max(batch, 1)  # one chunk per timed call
    config = SurrogateConfig(device="cpu", epochs=fit_epochs, batch_size=32, precision="fp32")
    surrogate = Surrogate(kind="two_stage", input_channels=domain.encoding_channels, input_shape=encoded.shape[2:],
                          occupancy_shape=domain.occupancy_shape, num_measures=len(domain.measure_names),
                          config=config, seed=0)
    dataset = surrogate.make_dataset()
    dataset.append(encoded=fit, results=results[:fit_levels])
    start = time.perf_counter()
    surrogate.train(dataset)
    train_s = time.perf_counter() - start
    error = surrogate.mae(heldout, results[fit_levels:])

    def predict(levels: np.ndarray, precision: str):
        surrogate.precision = precision  # the same trained weights, only the arithmetic changes
        return surrogate.predict(levels)

    # Agreement needs no real evaluation: both precisions predict the same unseen levels.
    fp32, bf16 = predict(agree, "fp32"), predict(agree, "bf16")
    archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges)
    same = (archive.int_to_grid_index(archive.index_of(fp32.measures))
            == archive.int_to_grid_index(archive.index_of(bf16.measures)))

    names = domain.measure_names
    print(f"bf16 surrogate: trained on {fit_levels} random valid levels x {episodes} episodes of {agent} "
          f"({evaluate_s:.0f} s), {fit_epochs} epochs ({train_s:.0f} s); MAE on {heldout_levels} held-out levels: "
          + ", ".join(f"{name} {error[f'measure_{i}']:.1f}" for i, name in enumerate(names)))
    print(f"bf16 / fp32 same archive cell: {same.all(axis=1).mean():.1%} of {agree_levels} unseen levels "
          f"({'x'.join(map(str, domain.archive_dims))} archive; per measure: "
          + ", ".join(f"{name} {share:.1%}" for name, share in zip(names, same.mean(axis=0)))
          + "; mean |bf16 - fp32|: "
          + ", ".join(f"{name} {d:.3f}" for name, d in zip(names, np.abs(bf16.measures - fp32.measures).mean(0)))
          + ")")

    batch_levels = agree[np.arange(batch) % len(agree)]
    previous = torch.get_num_threads()
    for count in threads:
        torch.set_num_threads(count)
        seconds: dict[str, list[float]] = {"fp32": [], "bf16": []}
        for _ in range(repeats):  # interleaved, so that load from other processes hits both alike
            for precision, times in seconds.items():
                times.append(best_time(lambda: predict(batch_levels, precision), calls=calls))
        fp32_rate, bf16_rate = (batch / min(seconds[p]) for p in ("fp32", "bf16"))
        print(f"bf16 / fp32 prediction throughput: {bf16_rate / fp32_rate:.2f}x ({count} thread{'s' * (count > 1)}, "
              f"batch {batch}: fp32 {fp32_rate:,.0f}/s, bf16 {bf16_rate:,.0f}/s; native CPU bf16: {native_cpu_bf16()})")
    torch.set_num_threads(previous)


def agreement(fp32: np.ndarray, bf16: np.ndarray, archive, names) -> str:
    """Share of levels both precisions put in the same archive cell, overall and per measure, and mean |Δ|."""
    same = (archive.int_to_grid_index(archive.index_of(fp32)) == archive.int_to_grid_index(archive.index_of(bf16)))
    return (f"same cell {same.all(axis=1).mean():.1%} (" + ", ".join(
        f"{name} {share:.1%}, mean |Δ| {d:.3f}" for name, share, d in
        zip(names, same.mean(axis=0), np.abs(bf16 - fp32).mean(axis=0))) + ")")


def bench_run_precision(run, *, levels: int) -> None:
    """(4): bf16 against fp32 on the surrogate a finished Maze run trained."""
    from pathlib import Path

    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.domains import build_domain

    state = load_checkpoint(Path(run) / CHECKPOINT_NAME)
    config = RunConfig.build(state["config"])
    if state.get("surrogate") is None or not state.get("holdout"):
        raise SystemExit(f"{run}: needs a surrogate run with held-out levels (experimental.holdout_levels > 0)")
    domain = build_domain(config)

    def encode(solutions):
        return pad_to_power_of_two(domain.encode(solutions), domain.encoding_pad_channel)

    names = domain.measure_names
    surrogate = Surrogate.for_domain(domain, config=config.surrogate, seed=0)
    surrogate.load_state_dict(state["surrogate"])
    archive = make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges)
    rng = np.random.default_rng(0)
    # The inner loop's queries: uniformly chosen elites with mutation_cells random cells redrawn.
    elites = state["archive"].data("solution")
    mutated = elites[rng.integers(0, len(elites), levels)].copy()
    for row in mutated:
        row[rng.choice(row.size, config.qd.mutation_cells, replace=False)] = rng.integers(0, 2, config.qd.mutation_cells)
    held = np.asarray(state["holdout"]["solutions"])
    truth = np.array([r.measures for r in state["holdout"]["results"]])
    print(f"run {run}: its trained surrogate ({config.surrogate.kind}, {len(state['history'])} outer iterations, "
          f"{config.maze.agent})")
    for label, solutions in ((f"{len(held)} held-out levels", held), (f"{levels} mutated archive elites", mutated)):
        encoded = encode(solutions)
        surrogate.precision = "fp32"
        fp32 = surrogate.predict(encoded).measures
        surrogate.precision = "bf16"
        bf16 = surrogate.predict(encoded).measures
        print(f"  bf16 / fp32 on {label}: {agreement(fp32, bf16, archive, names)}")
        if solutions is held:
            print("  the surrogate's own error there (fp32): MAE " + ", ".join(
                f"{name} {e:.1f}" for name, e in zip(names, np.abs(fp32 - truth).mean(axis=0))))


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


def setting_table(settings: list[str], *, threads: int, batch: int, repeats: int, calls: int, train_samples: int,
                  run: str | None, seeds: int, json_path: str | None = None) -> None:
    """(5): FLOPs, predictions/s, training s/epoch and (with ``run``) replayed accuracy per setting, one table."""
    import dataclasses

    from bench_surrogate_training import main as replay
    from bench_surrogate_training import parse_setting
    from metrics import format_mean_se, mean_se

    from dsage_ray.config import RunConfig

    parsed = [parse_setting(text) for text in settings]
    levels = random_valid_levels(max(batch, train_samples), seed=0, density_range=(0.0, 0.9))
    walls = np.stack([level.walls.reshape(-1) for level in levels]).astype(np.int8)
    rng = np.random.default_rng(0)
    cases = []
    for name, overrides in parsed:
        config = RunConfig.build({"preset": "cpu", "maze.agent": "builtin:wall_follower", **overrides})
        domain = MazeDomain(config=config.maze)
        encoded = pad_to_power_of_two(domain.encode(walls), domain.encoding_pad_channel)
        # One epoch per train() call; the epoch count and window are the replay's business.
        train_config = dataclasses.replace(config.surrogate, device="cpu", epochs=1, train_window=train_samples)
        surrogate = Surrogate.for_domain(domain, config=train_config, seed=0)
        dataset = surrogate.make_dataset()
        dataset.append(encoded=encoded[:train_samples], results=[
            EvaluationResult(objective=1.0, measures=rng.random(len(domain.measure_names)) * 100,
                             occupancy=rng.random(domain.occupancy_shape, dtype=np.float32))
            for _ in range(train_samples)])
        cases.append(dict(name=name, surrogate=surrogate, dataset=dataset, levels=encoded[:batch],
                          flops=flops_per_sample(surrogate.model, torch.from_numpy(encoded[:batch]))))
    torch.set_num_threads(threads)
    predict_s: dict[str, list[float]] = {case["name"]: [] for case in cases}
    train_s: dict[str, list[float]] = {case["name"]: [] for case in cases}
    for case in cases:  # trained before any timing, so that what a trained surrogate adds (a prior's blend) counts
        case["surrogate"].train(case["dataset"])
    for _ in range(repeats):  # interleaved, so that load from other processes hits every setting alike
        for case in cases:
            predict_s[case["name"]].append(best_time(lambda: case["surrogate"].predict(case["levels"]), calls=calls))
        for case in cases:
            train_s[case["name"]].append(best_time(lambda: case["surrogate"].train(case["dataset"]), calls=1))

    accuracy: dict[str, dict[str, tuple[float, float]]] = {}
    replays: dict[str, list] = {}
    if run is not None:
        for name, _ in parsed:
            body = next(text.partition(":")[2] for text in settings if text.partition(":")[0] == name)
            per_seed = []
            for seed in range(seeds):
                report = replay([run, "--threads", "1", "--setting", f"{name}:{body}{',' * bool(body)}seed={seed}"])
                per_seed.append(report["settings"][name]["iterations"])
            replays[name] = per_seed
            measure = [k for k in per_seed[0][0] if k.startswith("holdout_spearman_")][-1].removeprefix(
                "holdout_spearman_")
            accuracy[name] = {
                column: mean_se([float(np.mean([row[key] for row in rows])) for rows in per_seed])
                for column, key in (("train s/iter", "train_s"), ("ρ", f"holdout_spearman_{measure}"),
                                    ("MAE", f"mae_{measure}"), ("held-out MAE", f"holdout_mae_{measure}"))}

    print(f"\nsettings on the Maze cpu preset: {threads} torch thread{'s' * (threads > 1)}, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; predictions/s at batch {batch} and training s/epoch "
          f"on {train_samples} levels, best of {repeats} interleaved repeats")
    if accuracy:
        print(f"replay of {run} ({seeds} seed{'s' * (seeds > 1)}; per outer iteration, mean ± s.e. over seeds): "
              "held-out Spearman ρ and selected-batch MAE of the last measure")
    header = ["setting", "MFLOP", "predictions/s", "train s/epoch", *(next(iter(accuracy.values()), {}))]
    rows = []
    for case in cases:
        name = case["name"]
        row = [name, f"{case['flops'] / 1e6:.1f}", f"{batch / min(predict_s[name]):,.0f}", f"{min(train_s[name]):.2f}"]
        row += [format_mean_se(mean, se, ".3g") for mean, se in accuracy.get(name, {}).values()]
        rows.append(row)
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print(" | ".join(str(cell).ljust(width) for cell, width in zip(row, widths)))
    if json_path:
        import json

        with open(json_path, "w") as file:
            json.dump({"settings": settings, "threads": threads, "batch": batch, "table": [header, *rows],
                       "predict_s": predict_s, "train_epoch_s": train_s, "replays": replays}, file, indent=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    inner_loop = QDConfig()
    parser.add_argument("--batch", type=int, default=inner_loop.batch_size * inner_loop.num_emitters,
                        help="inner-loop batch (qd.batch_size x qd.num_emitters = 150 for the Maze)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--calls", type=int, default=20)
    parser.add_argument("--train-samples", type=int, default=2000)
    parser.add_argument("--train-batch", type=int, default=64)
    parser.add_argument("--train-epochs", type=int, default=3)
    # The wall follower is deterministic (one episode says all) and ~50x cheaper than ACCEL, whose 600 levels
    # take minutes on 2 cores; its path lengths span the same 0-648 range. --agent dcd:accel --episodes 5 works.
    parser.add_argument("--agent", default="builtin:wall_follower",
                        help="agent whose evaluations train the bf16/fp32 surrogate")
    parser.add_argument("--episodes", type=int, default=1, help="episodes per level for that surrogate's data")
    parser.add_argument("--fit-levels", type=int, default=500, help="evaluated levels the surrogate trains on")
    parser.add_argument("--heldout-levels", type=int, default=100, help="evaluated levels for its MAE")
    parser.add_argument("--agree-levels", type=int, default=1000, help="levels both precisions predict")
    parser.add_argument("--fit-epochs", type=int, default=20)
    parser.add_argument("--run", help="also: bf16/fp32 agreement of the surrogate this finished Maze run trained; "
                        "with --setting: the run whose data the replay trains on")
    parser.add_argument("--setting", action="append", default=[],
                        help="NAME:key=value,... on the Maze cpu preset (repeatable): only the settings table")
    parser.add_argument("--seeds", type=int, default=3, help="with --setting and --run: replays per setting")
    parser.add_argument("--json", help="with --setting: also write the table and every replayed iteration here")
    args = parser.parse_args()
    if args.setting:
        setting_table(args.setting, threads=args.threads, batch=args.batch, repeats=args.repeats, calls=args.calls,
                      train_samples=args.train_samples, run=args.run, seeds=args.seeds, json_path=args.json)
        return
    torch.set_num_threads(args.threads)
    # Other processes on the cores make multi-threaded small convolutions much slower (threads wait on
    # each other at every op): read the numbers against the load average.
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, mkldnn {torch.backends.mkldnn.is_available()}, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    bench_inference(batch=args.batch, repeats=args.repeats, calls=args.calls)
    bench_precision(batch=args.batch, repeats=args.repeats, calls=args.calls, threads=sorted({1, args.threads}),
                    agent=args.agent, episodes=args.episodes, fit_levels=args.fit_levels,
                    heldout_levels=args.heldout_levels, agree_levels=args.agree_levels, fit_epochs=args.fit_epochs)
    bench_training(samples=args.train_samples, batch_size=args.train_batch, epochs=args.train_epochs)
    if args.run:
        torch.set_num_threads(1)
        bench_run_precision(args.run, levels=args.agree_levels)


if __name__ == "__main__":
    main()
