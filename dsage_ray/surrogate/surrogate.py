"""Training and prediction around a surrogate network, with exact checkpoint/resume (SPEC: DSAGE and the surrogate).

The network and its ONE Adam optimizer live as long as the :class:`Surrogate`: DSAGE keeps
training the same model every outer iteration and never re-initialises it. All randomness
(initial weights, minibatch order) comes from ``seed`` through a dedicated generator, never the
global torch RNG, so other code cannot perturb it and a resumed run trains exactly as an
uninterrupted one.

Predictions run in ``config.precision`` (:func:`resolve_precision`). bf16 runs the two-stage model's residual
blocks, most of its arithmetic, in bf16 where the hardware computes bf16 natively; ``benchmarks/bench_surrogate.py``
measures it at the Maze inner-loop batch: throughput, and how many levels land in another cell of the Maze
archive (one wall wide: a few percent move by one cell, by ~100x less than the surrogate's own error).
Training always runs in float32.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from dsage_ray import kernels
from dsage_ray.config import SurrogateConfig
from dsage_ray.surrogate.dataset import SurrogateDataset, Targets
from dsage_ray.surrogate.grid_features import LevelStatistics
from dsage_ray.surrogate.models import (ModelOutput, OneStageModel, TwoStageModel, VectorOneStageModel,
                                       VectorTwoStageModel, encode_solutions)
from dsage_ray.types import EncodedLevels, EvaluationResult, LevelValuesDomain, PriorDomain

#: Encoded levels ``(n, C, S, S)`` → ``{measure name or "objective": (n,) values}``.
LevelValues = Callable[[np.ndarray], dict[str, np.ndarray]]

#: Surrogate kinds by name: ``two_stage`` predicts occupancy first (DSAGE), ``one_stage`` does not.
#: With ``"none"`` (plain QD, no surrogate) these are the config's ``surrogate.kind`` names. Each is
#: built from the input's shape and the config's width (``channels``).
#: A 1×1 input is a parameter vector (the gym domain's levels), which the vector models read with MLPs of
#: ``channels`` hidden units.
MODELS: dict[str, Callable[..., nn.Module]] = {
    "two_stage": lambda *, input_channels, input_size, occupancy_shape, num_measures, config, statistics=None:
        VectorTwoStageModel(input_channels=input_channels, occupancy_shape=occupancy_shape,
                            num_measures=num_measures, width=config.channels) if input_size == 1 else
        TwoStageModel(input_channels=input_channels, input_size=input_size, occupancy_shape=occupancy_shape,
                      num_measures=num_measures, channels=config.channels, statistics=statistics),
    "one_stage": lambda *, input_channels, input_size, occupancy_shape, num_measures, config, statistics=None:
        VectorOneStageModel(input_channels=input_channels, num_measures=num_measures, width=config.channels)
        if input_size == 1 else
        OneStageModel(input_channels=input_channels, input_size=input_size, num_measures=num_measures,
                      channels=config.channels, statistics=statistics),
}
KINDS = tuple(MODELS)
#: With ``prior_measure``: the prior's share of that measure's prediction (the network has the rest). An even
#: blend is what the fair benchmark scored (rank-averaging the networks with the random walker).
PRIOR_WEIGHT = 0.5
PRECISIONS = ("auto", "fp32", "bf16")
#: Levels per prediction chunk: bounds the memory of a prediction, not its result.
PREDICT_BATCH_SIZE = 4096
#: x86 CPU flags of native bf16 arithmetic. Without them bf16 is emulated and slower than float32.
#: (ARM's bf16 extensions are left out: never measured here, so ``auto`` keeps float32 there.)
NATIVE_BF16_FLAGS = ("avx512_bf16", "amx_bf16")


@dataclasses.dataclass
class Prediction:
    """Surrogate predictions for ``n`` levels (float32 numpy arrays).

    Attributes:
        objective: Shape ``(n,)``.
        measures: Shape ``(n, num_measures)``.
        occupancy: Shape ``(n, H, W)``; ``None`` for a one-stage model.
    """

    objective: np.ndarray
    measures: np.ndarray
    occupancy: np.ndarray | None


def resolve_device(name: str) -> torch.device:
    """``"auto"`` is CUDA when available, else CPU; anything else is passed to :class:`torch.device`."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


@functools.lru_cache(maxsize=None)
def native_cpu_bf16() -> bool:
    """Whether this CPU has native bf16 arithmetic (:data:`NATIVE_BF16_FLAGS`).

    ``torch.cpu.get_capabilities()`` (torch ≥ 2.8) reads the CPU's feature bits; older torch falls back
    to the kernel's ``/proc/cpuinfo`` flags. Anything unreadable counts as "no": float32 is always safe.
    """
    get_capabilities = getattr(torch.cpu, "get_capabilities", None)
    if get_capabilities is not None:
        try:
            capabilities = get_capabilities()
            return any(bool(capabilities.get(flag, False)) for flag in NATIVE_BF16_FLAGS)
        except Exception:  # a capability probe must never stop a run; fall through to /proc
            pass
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
    except OSError:
        return False
    flags = {flag for line in cpuinfo.splitlines() if line.startswith("flags") for flag in line.partition(":")[2].split()}
    return any(flag in flags for flag in NATIVE_BF16_FLAGS)


def resolve_precision(name: str, device: torch.device) -> str:
    """The prediction precision ``"fp32"`` or ``"bf16"`` that ``name`` means on ``device``.

    ``"auto"`` is bf16 on a CUDA device that computes bf16 natively and on a CPU with
    :func:`native_cpu_bf16` (unless :mod:`dsage_ray.kernels` are portable), else fp32. ``"fp32"`` and ``"bf16"`` are taken as given (bf16 on a CPU without
    native support works, just slowly).
    """
    if name not in PRECISIONS:
        raise ValueError(f"surrogate precision must be one of {PRECISIONS}, got {name!r}")
    if name != "auto":
        return name
    if device.type == "cuda":
        return "bf16" if torch.cuda.is_bf16_supported(including_emulation=False) else "fp32"
    if device.type == "cpu":
        return "bf16" if native_cpu_bf16() and not kernels.portable() else "fp32"
    return "fp32"


class Surrogate:
    """The deep surrogate model of DSAGE: fit on real evaluations, predict for the inner QD loop.

    Args:
        kind: ``"two_stage"`` (predicts occupancy first, DSAGE) or ``"one_stage"`` (no ancillary data).
        input_channels: Channels of the encoded levels.
        input_shape: ``(size, size)`` of the encoded levels; a power of two ≥ 8 (see
            :func:`~dsage_ray.surrogate.models.pad_to_power_of_two`).
        occupancy_shape: ``(H, W)`` of the occupancy grid, the top-left corner of the input grid.
        num_measures: Number of measures.
        config: Training and prediction settings.
        seed: Seeds the initial weights and the minibatch order.
        measure_names: The measures' names; required by ``config.occupancy_sum_measure``, which names one.
        statistics: Per-level scalars fed to the measure heads (:class:`~dsage_ray.surrogate.grid_features.LevelStatistics`).
        prior: With ``config.prior_measure``: the domain's parameter-free prior of that measure, encoded levels
            ``(n, C, S, S)`` → ``(n,)`` (Maze: :func:`~dsage_ray.domains.maze.prior.walker_prior`).
        sum_residual: The ``occupancy_sum_measure`` is the occupancy sum *plus* its head's output, which then
            learns the sum's error, instead of the sum alone.
        level_values: With ``config.exact_level_values``: the domain's values that are functions of the level
            alone, encoded levels → ``{measure name or "objective": (n,)}``. They replace the predictions of the
            same name; names that are not this surrogate's measures are ignored.

    ``statistics`` and ``sum_residual`` are not in the paper and no config key sets them:
    ``benchmarks/bench_surrogate_ceiling.py`` judges them (neither predicts a search's own levels better).
    """

    def __init__(self, *, kind: str, input_channels: int, input_shape: tuple[int, int],
                 occupancy_shape: tuple[int, int], num_measures: int, config: SurrogateConfig, seed: int,
                 measure_names: Sequence[str] | None = None, statistics: LevelStatistics | None = None,
                 sum_residual: bool = False, prior: Callable[[torch.Tensor], torch.Tensor] | None = None,
                 level_values: LevelValues | None = None) -> None:
        if kind not in KINDS:
            raise ValueError(f"surrogate kind must be one of {KINDS}, got {kind!r}")
        size, width = input_shape
        if size != width:
            raise ValueError(f"input must be square (pad with pad_to_power_of_two), got {input_shape}")
        self.kind = kind
        self.config = config
        self.input_channels = input_channels
        self.input_shape = (size, size)
        self.occupancy_shape = tuple(occupancy_shape)
        self.num_measures = num_measures
        self.device = resolve_device(config.device)
        self._sum_index = _occupancy_sum_index(config.occupancy_sum_measure, kind, measure_names, num_measures)
        self._sum_residual = sum_residual
        self._prior_index = _measure_index("prior_measure", config.prior_measure, measure_names, num_measures)
        if self._prior_index is not None and prior is None:
            raise ValueError(f"prior_measure {config.prior_measure!r} needs the domain's prior (none was given)")
        self._prior = prior
        if config.exact_level_values and level_values is None:
            raise ValueError("exact_level_values needs the domain's level_values (none was given)")
        self._level_values = level_values if config.exact_level_values else None
        self._measure_columns = {name: i for i, name in enumerate(measure_names or ())}
        #: ``(intercept, slope)`` of the measure on ``log(1 + prior)``, fitted by :meth:`train`; None before.
        self._prior_fit: tuple[float, float] | None = None
        #: ``"fp32"`` or ``"bf16"``: what ``config.precision`` resolved to on this machine.
        self.precision = resolve_precision(config.precision, self.device)
        # Weights are drawn on the CPU inside a forked RNG: the same seed gives the same network on
        # any device, and the global RNG stays untouched.
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            model = MODELS[kind](input_channels=input_channels, input_size=size,
                                 occupancy_shape=self.occupancy_shape, num_measures=num_measures, config=config,
                                 statistics=statistics)
        self.model = model.to(self.device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=config.lr)
        self._shuffle_rng = torch.Generator().manual_seed(seed)

    @classmethod
    def for_domain(cls, domain: Any, *, config: SurrogateConfig, seed: int) -> "Surrogate":
        """A ``config.kind`` surrogate shaped for ``domain``: its encoded levels, measures and prior.

        Every caller that builds the surrogate of a run (the proposer, ``surrogate pretrain``, the benchmarks'
        replays) goes through here, so a run's surrogate and theirs cannot differ in what they are given.

        Raises:
            ValueError: ``config`` names a measure the domain lacks, or a ``prior_measure`` it has no prior for.
        """
        sample = encode_solutions(domain, domain.random_solutions(1, np.random.default_rng(0)))
        return cls(kind=config.kind, input_channels=sample.shape[1], input_shape=tuple(sample.shape[2:]),
                   occupancy_shape=domain.occupancy_shape, num_measures=len(domain.measure_names), config=config,
                   seed=seed, measure_names=domain.measure_names,
                   prior=domain_prior(domain, config.prior_measure),
                   level_values=domain_level_values(domain) if config.exact_level_values else None)

    @property
    def measures_exact(self) -> bool:
        """Whether the level's own values replace every measure's prediction (``config.exact_level_values`` with a
        domain whose measures are all level values, e.g. a gym space's parameters): a level's archive cell is then
        known before it is played."""
        if self._level_values is None or self.num_measures == 0:
            return False
        sample = np.zeros((1, self.input_channels, *self.input_shape), np.float32)
        return set(self._measure_columns) <= set(self._level_values(sample)) and \
            len(self._measure_columns) == self.num_measures

    @property
    def head_names(self) -> tuple[str, ...]:
        """Names of the predicted quantities, as used in :meth:`train` and :meth:`mae` results."""
        names = ("objective", *(f"measure_{i}" for i in range(self.num_measures)))
        model = self.model
        # A wrapper (models.WithInputFields) predicts what the network it wraps predicts.
        while not isinstance(model, TwoStageModel) and hasattr(model, "model"):
            model = model.model
        return (*names, "occupancy") if isinstance(model, (TwoStageModel, VectorTwoStageModel)) else names

    def make_dataset(self, **kwargs: Any) -> SurrogateDataset:
        """An empty dataset whose shapes match this model; ``kwargs`` go to :class:`SurrogateDataset`."""
        return SurrogateDataset(level_shape=(self.input_channels, *self.input_shape), num_measures=self.num_measures,
                                occupancy_shape=self.occupancy_shape, **kwargs)

    # ----------------------------------------------------------------------------------- training

    def _losses(self, output: ModelOutput, objective: torch.Tensor, measures: torch.Tensor,
                occupancy: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Returns the training loss and the per-head MSEs (``head_names`` order)."""
        output = self._sum_occupancy(output)
        predicted = torch.cat([output.objective[:, None], output.measures], dim=1)
        target = torch.cat([objective[:, None], measures], dim=1)
        head_mse = F.mse_loss(predicted, target, reduction="none").mean(dim=0)
        loss = head_mse.mean()
        if output.occupancy is None:
            return loss, head_mse
        occupancy_mse = F.mse_loss(output.occupancy, occupancy)
        return loss + self.config.occupancy_weight * occupancy_mse, torch.cat([head_mse, occupancy_mse[None]])

    def train(self, dataset: SurrogateDataset) -> dict[str, float]:
        """Fits the model on the most recent ``config.train_window`` samples.

        Trains ``config.epochs`` epochs. The weights and Adam's moments persist, so a later training starts
        from a fitted model.

        Returns:
            The last epoch's sample-weighted mean MSE per head (``head_names``; occupancy unweighted),
            ``"total"``, the loss that was minimised, and ``"epochs"``, the epochs trained.
        """
        window = dataset.recent(self.config.train_window)
        n = len(window)
        if n == 0:
            raise ValueError("cannot train the surrogate on an empty dataset")
        batch_size = self.config.batch_size
        for _ in range(self.config.epochs):
            self.model.train()
            order = torch.randperm(n, generator=self._shuffle_rng).numpy()
            # Accumulated on the device: one host sync per epoch, not one per minibatch.
            sums = torch.zeros(len(self.head_names) + 1, device=self.device)
            for start in range(0, len(order), batch_size):
                indices = order[start:start + batch_size]
                levels, *targets = window.batch(indices, self.device)
                loss, head_mse = self._losses(self.model(levels), *targets)
                self.optimizer.zero_grad(set_to_none=True)
                loss.backward()
                self.optimizer.step()
                sums += torch.cat([head_mse, loss[None]]).detach() * len(indices)
        losses = dict(zip((*self.head_names, "total"), (sums / n).tolist()))
        losses["epochs"] = float(self.config.epochs)
        if self._prior_index is not None:
            self._prior_fit = self._fit_prior(window)
        return losses

    def training_step_seconds(self, dataset: SurrogateDataset) -> float:
        """Seconds of one training step (forward and backward on ``config.batch_size`` recent samples), timed on a
        copy of the model: the model, its optimiser, its batch-norm statistics and its random streams are untouched.

        The second of two steps is timed, as the first carries one-off allocations.
        """
        window = dataset.recent(self.config.train_window)
        if len(window) == 0:
            raise ValueError("cannot time a training step on an empty dataset")
        model = copy.deepcopy(self.model).train()
        indices = np.arange(min(self.config.batch_size, len(window)))
        seconds = 0.0
        for _ in range(2):
            tic = time.perf_counter()
            levels, *targets = window.batch(indices, self.device)
            loss, _ = self._losses(model(levels), *targets)
            loss.backward()
            model.zero_grad(set_to_none=True)
            seconds = time.perf_counter() - tic
        return seconds

    def _log_prior(self, encoded: np.ndarray) -> np.ndarray:
        """``log(1 + prior)`` of ``(n, C, S, S)`` float32 levels, float64, in chunks of :data:`PREDICT_BATCH_SIZE`."""
        step = PREDICT_BATCH_SIZE
        parts = [self._prior(torch.from_numpy(encoded[start:start + step])).double().cpu().numpy()
                 for start in range(0, len(encoded), step)]
        return np.log1p(np.concatenate(parts)) if parts else np.zeros(0)

    def _fit_prior(self, window) -> tuple[float, float] | None:
        """The least-squares line of the prior measure on ``log(1 + prior)`` over the window's levels."""
        target = np.asarray(window.measures[:, self._prior_index], dtype=np.float64)
        log_prior = self._log_prior(window.batch(np.arange(len(window)), torch.device("cpu"))[0].numpy())
        finite = np.isfinite(target) & np.isfinite(log_prior)
        if finite.sum() < 2 or np.ptp(log_prior[finite]) == 0:
            return None
        slope, intercept = np.polyfit(log_prior[finite], target[finite], 1)
        return float(intercept), float(slope)

    def _sum_occupancy(self, output: ModelOutput) -> ModelOutput:
        """Replaces the ``occupancy_sum_measure`` head's output by the sum of the predicted occupancy.

        The loss on that measure then trains the occupancy predictor directly, and its prediction
        is consistent with the predicted occupancy by construction. With ``sum_residual`` the head's
        output is added to the sum instead.
        """
        if self._sum_index is None:
            return output
        i = self._sum_index
        total = output.occupancy.float().sum(dim=(1, 2))
        if self._sum_residual:
            total = total + output.measures[:, i]
        measures = torch.cat([output.measures[:, :i], total[:, None], output.measures[:, i + 1:]], dim=1)
        return output._replace(measures=measures)

    # --------------------------------------------------------------------------------- prediction

    def predict(self, encoded: EncodedLevels) -> Prediction:
        """Predicts for ``(n, input_channels, size, size)`` levels in chunks of :data:`PREDICT_BATCH_SIZE`.

        With :attr:`precision` ``"bf16"`` the two-stage model's residual blocks run in bf16
        (:meth:`~dsage_ray.surrogate.models.OccupancyPredictor.forward`); the results are float32 either way.
        """
        encoded = np.ascontiguousarray(encoded, dtype=np.float32)
        expected = (self.input_channels, *self.input_shape)
        if encoded.ndim != 4 or encoded.shape[1:] != expected:
            raise ValueError(f"expected levels of shape (n, {', '.join(map(str, expected))}), got {encoded.shape}")
        self.model.eval()
        chunks: list[ModelOutput] = []
        with torch.inference_mode():
            for start in range(0, len(encoded), PREDICT_BATCH_SIZE):
                levels = torch.from_numpy(encoded[start:start + PREDICT_BATCH_SIZE]).to(self.device)
                chunks.append(self.model(levels, bf16_blocks=self.precision == "bf16"))
        if not chunks:
            height, width = self.occupancy_shape
            return Prediction(objective=np.zeros(0, np.float32), measures=np.zeros((0, self.num_measures), np.float32),
                              occupancy=np.zeros((0, height, width), np.float32) if "occupancy" in self.head_names else None)
        objective, measures, occupancy = (None if parts[0] is None else torch.cat(parts)
                                          for parts in zip(*map(self._sum_occupancy, chunks)))
        measures = measures.cpu().numpy()
        if self._prior_fit is not None:
            intercept, slope = self._prior_fit
            i = self._prior_index
            from_prior = intercept + slope * self._log_prior(encoded)
            measures[:, i] = (PRIOR_WEIGHT * from_prior + (1.0 - PRIOR_WEIGHT) * measures[:, i]).astype(np.float32)
        objective = objective.cpu().numpy()
        if self._level_values is not None:
            for name, values in self._level_values(encoded).items():
                column = objective if name == "objective" else (
                    measures[:, self._measure_columns[name]] if name in self._measure_columns else None)
                if column is not None:
                    column[:] = values
        return Prediction(objective, measures, None if occupancy is None else occupancy.cpu().numpy())

    def mae(self, encoded: EncodedLevels, results: Sequence[EvaluationResult],
            prediction: Prediction | None = None) -> dict[str, float]:
        """Mean absolute error of the predictions against real results, per head (failed results skipped).

        Args:
            encoded: The evaluated levels.
            results: Their real results.
            prediction: ``predict(encoded)`` when the caller already has it (saves a second pass).

        Returns:
            ``{head: MAE}`` over ``head_names`` (occupancy: mean over cells and levels); empty when
            every result failed.
        """
        targets = Targets.from_results(results, num_measures=self.num_measures, occupancy_shape=self.occupancy_shape)
        if not targets.valid.any():
            return {}
        if prediction is None:
            prediction = self.predict(np.asarray(encoded)[targets.valid])
        else:
            prediction = Prediction(**{
                name: None if value is None else value[targets.valid]
                for name, value in dataclasses.asdict(prediction).items()
            })
        errors = np.abs(prediction.measures - targets.measures).mean(axis=0)
        mae = {"objective": float(np.abs(prediction.objective - targets.objective).mean()),
               **{f"measure_{i}": float(e) for i, e in enumerate(errors)}}
        if prediction.occupancy is not None:
            mae["occupancy"] = float(np.abs(prediction.occupancy - targets.occupancy).mean())
        return mae

    # -------------------------------------------------------------------------------- checkpoints

    def state_dict(self) -> dict[str, Any]:
        """Model, optimizer and shuffling RNG, as CPU copies (later training does not alter them)."""
        return {
            "kind": self.kind,
            "model": _cpu_copy(self.model.state_dict()),
            "optimizer": _cpu_copy(self.optimizer.state_dict()),
            "shuffle_rng": self._shuffle_rng.get_state(),
            "prior_fit": self._prior_fit,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if state["kind"] != self.kind:
            raise ValueError(f"checkpoint holds a {state['kind']} surrogate, this one is {self.kind}")
        self.model.load_state_dict(state["model"])
        # Adam adopts the given tensors as its moment buffers (moving them to the parameters' device
        # only if needed) and updates them in place: copy, so the checkpoint itself never changes.
        self.optimizer.load_state_dict(_cpu_copy(state["optimizer"]))
        self._shuffle_rng.set_state(state["shuffle_rng"])
        # Checkpoints from before prior_measure existed hold no fit: the next training fits one.
        self._prior_fit = state.get("prior_fit")


def domain_prior(domain: Any, measure: str) -> Callable[[torch.Tensor], torch.Tensor] | None:
    """The ``Surrogate(prior=...)`` of ``config.prior_measure``: the domain's ``surrogate_prior(measure)``.

    Raises:
        ValueError: A measure is named and the domain has no prior for it.
    """
    if not measure:
        return None
    prior = domain.surrogate_prior(measure) if isinstance(domain, PriorDomain) else None
    if prior is None:
        raise ValueError(f"surrogate.prior_measure {measure!r}: the {getattr(domain, 'name', '?')} domain has no "
                         "prior for it")
    return prior


def domain_level_values(domain: Any) -> LevelValues:
    """The ``Surrogate(level_values=...)`` of ``config.exact_level_values``: the domain's ``level_values``.

    Raises:
        ValueError: The domain computes nothing from the level alone.
    """
    if not isinstance(domain, LevelValuesDomain):
        raise ValueError(f"surrogate.exact_level_values: the {getattr(domain, 'name', '?')} domain computes no "
                         "measure from the level alone (it has no level_values)")
    return domain.level_values


def _occupancy_sum_index(name: str, kind: str, measure_names: Sequence[str] | None,
                         num_measures: int) -> int | None:
    """The index of ``config.occupancy_sum_measure`` among the measures, or None when it is unset."""
    if name and kind != "two_stage":
        raise ValueError(f"occupancy_sum_measure {name!r} needs the two_stage surrogate, not {kind!r}")
    return _measure_index("occupancy_sum_measure", name, measure_names, num_measures)


def _measure_index(key: str, name: str, measure_names: Sequence[str] | None, num_measures: int) -> int | None:
    """The index of the measure ``name`` that config ``key`` names, or None when it is unset."""
    if not name:
        return None
    names = list(measure_names or ())
    if len(names) != num_measures or name not in names:
        raise ValueError(f"{key} {name!r} is not one of the measures {names}")
    return names.index(name)


def _cpu_copy(tree: Any) -> Any:
    if isinstance(tree, torch.Tensor):
        return tree.detach().to("cpu", copy=True)
    if isinstance(tree, dict):
        return type(tree)((k, _cpu_copy(v)) for k, v in tree.items())
    if isinstance(tree, (list, tuple)):
        return type(tree)(_cpu_copy(v) for v in tree)
    return tree
