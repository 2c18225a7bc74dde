"""Warm starts: a surrogate trained before the run, and what it was trained on (beyond the paper).

A user audits the same agent, or the next checkpoint of its training, many times. Each cold DSAGE
run spends its first outer iterations learning what the last run's surrogate already knew. With
``surrogate.init`` a run starts from an earlier surrogate instead:

* its **weights** replace the freshly initialised ones (Adam starts afresh, with the run's ``lr``);
* its **dataset** becomes the oldest part of the run's dataset when ``experimental.init_prior`` is on
  (the default). Training reads the most recent ``surrogate.train_window`` samples, so the prior
  weighs fully in the first trainings and leaves the window as the run's own evaluations arrive:
  it is only a prior when the agent has changed;
* the first outer iteration **exploits the loaded model** instead of evaluating ``n_rand`` random
  levels.

``surrogate.init`` names a file ``dsage-ray surrogate pretrain`` wrote, or any earlier surrogate
run: a run folder, an audit folder, a Tune trial folder or a ``checkpoint.dsage`` file. Both hold
the same parts (a config, the surrogate's state, its dataset), so one loader reads them all. The
source must have the run's network (surrogate ``kind``, ``channels``, summed measure) and level encoding; anything else may differ, the agent included.

Nothing here touches the run's RNG streams: a warm-started run is as reproducible as a cold one.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.config import ConfigError
from dsage_ray.errors import InputError

#: ``format`` of a pretrained-surrogate file (a :mod:`dsage_ray.core.checkpoint` file holding this dict).
PRETRAINED_FORMAT = "dsage_ray pretrained surrogate"
#: Surrogate config keys that shape the network's weights or their meaning: a source must match them.
ARCHITECTURE_KEYS = ("kind", "channels", "occupancy_sum_measure")


class SurrogateInitError(InputError):
    """A ``surrogate.init`` source that cannot warm-start this run; the message names the path and why."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class WarmStart:
    """A surrogate and its dataset, read from a pretrained file or an earlier run.

    Attributes:
        path: The file it was read from.
        config: The config of the run (or pretraining) that trained it.
        surrogate: :meth:`~dsage_ray.surrogate.Surrogate.state_dict` of the trained surrogate.
        dataset: :meth:`~dsage_ray.surrogate.SurrogateDataset.state_dict` of what it was trained on.
        agent: The agent it predicts (its spec), when the source names one.
        info: What pretraining reported (levels, epochs, held-out ρ, seconds); empty for a run.
    """

    path: Path
    config: RunConfig
    surrogate: Mapping[str, Any]
    dataset: Mapping[str, Any]
    agent: str | None = None
    info: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def levels(self) -> int:
        """Samples in its dataset."""
        return int(len(self.dataset["objective"]))

    def check_compatible(self, config: RunConfig, *, level_shape: Sequence[int]) -> None:
        """Raises :class:`SurrogateInitError` naming the first thing that keeps it from warm-starting ``config``.

        Args:
            config: The run to warm-start.
            level_shape: ``(channels, size, size)`` of that run's encoded levels.
        """
        def fail(why: str) -> SurrogateInitError:
            return SurrogateInitError(f"surrogate.init {str(self.path)!r}: {why}")

        if self.config.domain != config.domain:
            raise fail(f"a {self.config.domain} surrogate, this run is {config.domain}")
        for key in ARCHITECTURE_KEYS:
            theirs, ours = getattr(self.config.surrogate, key), getattr(config.surrogate, key)
            if tuple(np.atleast_1d(theirs)) != tuple(np.atleast_1d(ours)):
                raise fail(f"trained with surrogate.{key}={theirs!r}, this run has {ours!r} (set "
                           f"surrogate.{key}={theirs!r}, or pretrain for this config)")
        theirs_shape = tuple(int(d) for d in self.dataset["level_shape"])
        if theirs_shape != tuple(level_shape):
            raise fail(f"its levels are encoded as {theirs_shape}, this run's as {tuple(level_shape)} (another "
                       f"{config.domain} encoding setting, e.g. {config.domain}.path_channels)")
        their_measures = _measure_names(self.config)
        our_measures = _measure_names(config)
        if their_measures is not None and our_measures is not None and their_measures != our_measures:
            raise fail(f"predicts the measures {list(their_measures)}, this run's are {list(our_measures)}")


def check_warm_start(config: RunConfig, *, domain=None) -> WarmStart | None:
    """Loads ``config.surrogate.init`` and checks it fits ``config``: every entry point's preflight calls this,
    so a wrong file fails in one line before any evaluation. None without ``surrogate.init``. ``domain``: the
    config's domain when the caller has built it already.

    Raises:
        SurrogateInitError: As :func:`load_warm_start` and :meth:`WarmStart.check_compatible`.
    """
    if not config.surrogate.init:
        return None
    from dsage_ray.domains import build_domain
    from dsage_ray.surrogate.models import encode_solutions

    domain = build_domain(config) if domain is None else domain
    sample = encode_solutions(domain, domain.random_solutions(1, np.random.default_rng(0)))
    source = load_warm_start(config.surrogate.init)
    source.check_compatible(config, level_shape=sample.shape[1:])
    return source


def _measure_names(config: RunConfig) -> tuple[str, ...] | None:
    names = getattr(config.domain_config, "measures", None)
    return None if names is None else tuple(names)


def find_checkpoint(path: str | Path) -> Path:
    """The checkpoint file that ``path`` names or holds: itself, ``checkpoint.dsage`` in a run or audit
    folder, or the latest ``checkpoint_NNNNNN`` of a Tune trial below it.

    Raises:
        SurrogateInitError: Nothing there, or a folder without a checkpoint.
    """
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME

    path = Path(path).expanduser()
    if path.is_file():
        return path
    if not path.exists():
        raise SurrogateInitError(f"surrogate.init {str(path)!r}: no such file or folder")
    for direct in (path / CHECKPOINT_NAME, path / "search" / CHECKPOINT_NAME):
        if direct.is_file():
            return direct
    in_tune = sorted(path.glob(f"**/checkpoint_*/{CHECKPOINT_NAME}"),
                     key=lambda p: (p.stat().st_mtime, int(p.parent.name.rsplit("_", 1)[-1])))
    if not in_tune:
        raise SurrogateInitError(f"surrogate.init {str(path)!r}: a folder without a run checkpoint "
                                 f"({CHECKPOINT_NAME}); pass a pretrained file, a run, audit or trial folder")
    return in_tune[-1]


def load_warm_start(path: str | Path) -> WarmStart:
    """Reads a pretrained-surrogate file or an earlier surrogate run (module docstring).

    Raises:
        SurrogateInitError: A missing, foreign or damaged file, or a run without a surrogate.
    """
    from dsage_ray.core.checkpoint import CheckpointError, load_checkpoint

    file = find_checkpoint(path)
    try:
        state = load_checkpoint(file)
    except CheckpointError as exc:
        raise SurrogateInitError(f"surrogate.init: {exc}") from None
    missing = [key for key in ("config", "surrogate", "dataset") if state.get(key) is None]
    if missing:
        what = ("a run without a surrogate (MAP-Elites, CMA-ME or DR): nothing to warm-start from"
                if "config" not in missing else f"not a surrogate checkpoint (no {', '.join(missing)})")
        raise SurrogateInitError(f"surrogate.init {str(file)!r}: {what}")
    try:
        config = RunConfig.build(state["config"])
    except ConfigError as exc:
        raise SurrogateInitError(f"surrogate.init {str(file)!r}: its config does not load here ({exc})") from None
    return WarmStart(path=file, config=config, surrogate=state["surrogate"], dataset=state["dataset"],
                     agent=state.get("agent") or _agent_of(config), info=state.get("pretrained", {}))


def _agent_of(config: RunConfig) -> str | None:
    agent = getattr(config.domain_config, "agent", None)
    return agent if isinstance(agent, str) else None


def pretrain(*, sources: Sequence[WarmStart], config: RunConfig, out: str | Path, seed: int = 0,
             epochs: int | None = None, validation_fraction: float = 0.1,
             progress: Callable[[int, int], None] | None = None) -> WarmStart:
    """Trains a fresh surrogate of ``config`` on every sample of ``sources`` and saves it to ``out``.

    Unlike a run, which trains on its most recent ``train_window`` samples, pretraining reads all of
    them. A random ``validation_fraction`` of the levels is held out for the reported Spearman ρ of
    each measure, and then trained on too.

    Args:
        sources: Warm starts (pretrained files or runs) whose datasets are pooled, in order.
        config: The config whose surrogate is trained (network, ``epochs``, ``batch_size``, ``lr``).
        out: The file to write.
        seed: Seeds the weights, the minibatch order and the held-out split.
        epochs: Epochs (default ``config.surrogate.epochs``).
        validation_fraction: Share of levels held out for the reported accuracy; 0: none.
        progress: Called with ``(epoch, epochs)`` after each epoch.

    Returns:
        The pretrained surrogate, as a later :func:`load_warm_start` of ``out`` reads it.

    Raises:
        SurrogateInitError: No sources, or sources of another encoding or network than ``config``.
    """
    from dsage_ray.core.checkpoint import save_checkpoint
    from dsage_ray.core.threads import torch_threads
    from dsage_ray.domains import build_domain
    from dsage_ray.surrogate.models import encode_solutions
    from dsage_ray.surrogate.surrogate import Surrogate

    if not sources:
        raise SurrogateInitError("surrogate pretrain: no source runs or files to train on")
    domain = build_domain(config)
    sample = encode_solutions(domain, domain.random_solutions(1, np.random.default_rng(0)))
    for source in sources:
        source.check_compatible(config, level_shape=sample.shape[1:])
    epochs = config.surrogate.epochs if epochs is None else epochs
    started = time.perf_counter()
    pooled = config.replace(**{"surrogate.epochs": 1})
    surrogate = Surrogate.for_domain(domain, config=pooled.surrogate, seed=seed)
    dataset = concatenate_datasets(surrogate, [source.dataset for source in sources])
    rng = np.random.default_rng(seed)
    held = np.sort(rng.permutation(len(dataset))[:int(len(dataset) * validation_fraction)])
    train_rows = np.setdiff1d(np.arange(len(dataset)), held)
    training = subset(surrogate, dataset, train_rows)
    surrogate.config = dataclasses.replace(pooled.surrogate, train_window=max(len(training), 1))
    with torch_threads(config.torch_threads):
        for epoch in range(1, epochs + 1):
            surrogate.train(training)
            if progress is not None:
                progress(epoch, epochs)
        spearman = _spearman(surrogate, dataset, held, measure_names=domain.measure_names)
        if len(held):  # the reported accuracy is measured; the saved model then learns every level
            surrogate.config = dataclasses.replace(surrogate.config, train_window=len(dataset))
            surrogate.train(dataset)
    info = {"levels": len(dataset), "epochs": epochs, "seed": seed, "held_out": int(len(held)),
            "held_out_spearman": spearman, "seconds": time.perf_counter() - started,
            "sources": [str(source.path) for source in sources]}
    agents = sorted({source.agent for source in sources if source.agent})
    state = {"format": PRETRAINED_FORMAT, "config": config.to_dict(), "surrogate": surrogate.state_dict(),
             "dataset": dataset.state_dict(), "agent": agents[0] if len(agents) == 1 else None,
             "pretrained": info}
    path = save_checkpoint(state, out)
    return WarmStart(path=path, config=config, surrogate=state["surrogate"], dataset=state["dataset"],
                     agent=state["agent"], info=info)


def pretrain_surrogate(sources: Sequence[str | Path], *, out: str | Path, overrides: Mapping[str, Any] | None = None,
                       epochs: int | None = None, seed: int = 0,
                       progress: Callable[[int, int], None] | None = None) -> WarmStart:
    """Pretrains a surrogate on earlier surrogate runs, audits or pretrained files: ``dsage-ray surrogate pretrain
    --from`` from Python (``dsage_ray.pretrain_surrogate``).

    Args:
        sources: Run, audit or Tune trial folders, checkpoint files or pretrained files; their levels are pooled.
        out: The file to write (``--surrogate-init`` / ``surrogate.init`` then reads it).
        overrides: Dotted config keys changed from the first source's config (e.g. ``{"surrogate.epochs": 30}``).
        epochs, seed, progress: As in :func:`pretrain`.

    Returns:
        The pretrained surrogate; ``.info`` holds its held-out Spearman ρ per predicted quantity.

    Raises:
        SurrogateInitError: A source that does not load or does not fit the others' network and encoding.
    """
    loaded = [load_warm_start(path) for path in sources]
    if not loaded:
        raise SurrogateInitError("surrogate pretrain: no source runs or files to train on")
    config = loaded[0].config.replace(**dict(overrides)) if overrides else loaded[0].config
    return pretrain(sources=loaded, config=config, out=out, seed=seed, epochs=epochs, progress=progress)


def concatenate_datasets(surrogate, states: Sequence[Mapping[str, Any]]):
    """One dataset of ``surrogate``'s shapes holding every sample of ``states`` (dataset state dicts), in order."""
    dataset = surrogate.make_dataset()
    keys = ("levels", "objective", "measures", "occupancy")
    merged = {key: np.concatenate([np.asarray(state[key]) for state in states]) for key in keys}
    dataset.load_state_dict({**merged, "level_shape": dataset.level_shape})
    return dataset


def subset(surrogate, dataset, rows: np.ndarray):
    """A dataset of ``surrogate``'s shapes holding ``dataset``'s samples at ``rows``."""
    state = dataset.state_dict()
    return concatenate_datasets(surrogate, [{key: (value[rows] if isinstance(value, np.ndarray) else value)
                                             for key, value in state.items()}])


def _spearman(surrogate, dataset, rows: np.ndarray, *, measure_names: Sequence[str]) -> dict[str, float]:
    """Spearman ρ of the predicted against the real objective and each measure on ``rows`` (empty with < 3)."""
    from scipy.stats import spearmanr

    if len(rows) < 3:
        return {}
    prediction = surrogate.predict(dataset.levels(rows))
    pairs = {"objective": (prediction.objective, dataset.objective[rows]),
             **{name: (prediction.measures[:, i], dataset.measures[rows, i]) for i, name in enumerate(measure_names)}}
    result = {}
    for name, (predicted, real) in pairs.items():
        if np.ptp(predicted) == 0 or np.ptp(real) == 0:  # a constant has no rank order: ρ is undefined
            result[name] = float("nan")
            continue
        rho = spearmanr(predicted, real).statistic
        result[name] = float(rho) if np.isfinite(rho) else float("nan")
    return result
