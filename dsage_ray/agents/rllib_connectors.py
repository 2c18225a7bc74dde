"""An RLlib algorithm checkpoint's connector pipelines, restored and applied as RLlib's env runner does at inference.

An algorithm checkpoint (``algo.save_to_path``) keeps the env runner's pipelines beside the module:
``env_runner/env_to_module_connector`` and ``env_runner/module_to_env_connector`` (or both at the top of the
checkpoint when training had only remote env runners). A policy trained behind an observation filter, frame
stacking or flattening only ever saw observations that went through the env-to-module pipeline, so it must be
played behind the same pipeline. Both are restored with RLlib's own ``ConnectorPipelineV2.from_checkpoint``.

Env-to-module: every connector below is run by RLlib itself, on one ``SingleAgentEpisode`` per running episode,
which holds every observation and action the agent saw (rewards are unknown to an agent and recorded as 0):

* RLlib's default pieces (observations and recurrent state to the batch, time axis, batching, tensors);
* ``MeanStdFilter``, frozen with its saved statistics (rebuilt with ``update_stats=False``: playing must not move
  them, nor make one episode's input depend on the others in the batch);
* ``FlattenObservations``, ``FrameStacking`` (``FrameStackingEnvToModule``), ``PrevActionsPrevRewards`` with
  ``n_prev_rewards=0``, and any ``SingleAgentObservationPreprocessor`` (RLlib's API for an observation transform).

Refused, in one :class:`AgentError` line naming the connector: ``PrevActionsPrevRewards`` with previous rewards (an
agent is never told its rewards), multi-agent pipelines (``AgentToModuleMapping``) and any other connector.

Module-to-env: RLlib's pieces there sample actions with torch's generator; the agents sample from the module's
``ACTION_DIST_INPUTS`` with the caller's numpy ``rng`` instead (reproducible evaluations) and do what the default
pieces do themselves. ``NormalizeAndClipActions`` is read for its ``normalize_actions`` setting (the default of the
gym agents' ``normalize_actions`` option); any other non-default connector is refused in one line.

A pipeline made only of RLlib's default pieces changes nothing the agents do not do already: it is checked, and
the agents then keep their direct (faster) batch path.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.loader import describe_exception

#: Where the local env runner's state lies in an algorithm checkpoint (RLlib's ``COMPONENT_ENV_RUNNER``).
ENV_RUNNER_DIR = "env_runner"
#: The pipelines' folders (RLlib's ``COMPONENT_ENV_TO_MODULE_CONNECTOR`` / ``COMPONENT_MODULE_TO_ENV_CONNECTOR``).
ENV_TO_MODULE_DIR = "env_to_module_connector"
MODULE_TO_ENV_DIR = "module_to_env_connector"

#: RLlib's default env-to-module pieces: what the agents' direct batch path does already.
DEFAULT_ENV_TO_MODULE = frozenset({"AddObservationsFromEpisodesToBatch", "AddTimeDimToBatchAndZeroPad",
                                   "AddStatesFromEpisodesToBatch", "BatchIndividualItems", "NumpyToTensor"})
#: Env-to-module connectors that transform what the module sees, run as restored (or frozen).
SUPPORTED_ENV_TO_MODULE = ("MeanStdFilter", "FlattenObservations", "FrameStacking", "PrevActionsPrevRewards",
                           "SingleAgentObservationPreprocessor")
#: RLlib's default module-to-env pieces, reproduced by the agents (sampling with the caller's rng, unbatching...).
DEFAULT_MODULE_TO_ENV = frozenset({"GetActions", "TensorToNumpy", "UnBatchToIndividualItems",
                                   "RemoveSingleTsTimeRankFromBatch", "NormalizeAndClipActions",
                                   "ListifyDataForVectorEnv"})


def pipelines_dir(checkpoint: Path) -> Path | None:
    """The folder that holds an algorithm checkpoint's env-to-module pipeline, or None where there is none."""
    for folder in (checkpoint / ENV_RUNNER_DIR, checkpoint):
        if (folder / ENV_TO_MODULE_DIR).is_dir():
            return folder
    return None


@dataclasses.dataclass
class EpisodeState:
    """The agent state of a pipeline-played batch: one ``SingleAgentEpisode`` per running episode.

    An agent's step is :meth:`ConnectorPipelines.module_batch` (the new observations join the episodes), the
    module, :meth:`after` (its outputs) and :meth:`acted` (the actions): both are added to the episodes with the
    next observations, as RLlib's env runner adds them. The episodes grow in place, so a state is used once.

    Attributes:
        episodes: What each running episode has shown the agent so far (observations after the pipeline's
            in-place transforms, as RLlib's episodes hold them).
        actions: Each episode's last action; None before the first.
        extras: Each episode's last module outputs that RLlib keeps in the episode (``STATE_OUT``), or None.
    """

    episodes: list
    actions: list | None = None
    extras: list | None = None

    def select(self, index: np.ndarray) -> "EpisodeState":
        """Only the episodes at ``index`` (the ones still running), as :meth:`Agent.select_state` asks."""
        rows = [int(i) for i in np.asarray(index).reshape(-1)]
        pick = (lambda items: None if items is None else [items[i] for i in rows])
        return EpisodeState(episodes=pick(self.episodes), actions=pick(self.actions), extras=pick(self.extras))

    def after(self, outputs: dict[str, Any]) -> "EpisodeState":
        """This state with the module's ``outputs`` of this step kept per episode (``STATE_OUT``, as numpy)."""
        from ray.rllib.core.columns import Columns

        if Columns.STATE_OUT not in outputs:
            return dataclasses.replace(self, extras=None)
        import tree

        state_out = tree.map_structure(lambda t: t.detach().cpu().numpy(), outputs[Columns.STATE_OUT])
        extras = [{Columns.STATE_OUT: tree.map_structure(lambda x, i=row: x[i], state_out)}
                  for row in range(len(self.episodes))]
        return dataclasses.replace(self, extras=extras)

    def acted(self, actions: np.ndarray) -> "EpisodeState":
        """This state with the actions of this step (one row per episode)."""
        return dataclasses.replace(self, actions=list(np.asarray(actions)))


@dataclasses.dataclass(frozen=True)
class ConnectorPipelines:
    """A checkpoint's restored pipelines (module docstring); build with :func:`load_pipelines`.

    Attributes:
        env_to_module: RLlib's restored env-to-module pipeline, filters frozen.
        input_observation_space: The observation space the pipeline takes: the environment's.
        input_action_space: The action space it was built for (the episodes' padding of missing steps reads it).
        transforms: The non-default env-to-module connectors' class names, in order; empty: the pipeline does
            nothing the agents' direct path does not (play without it).
        normalize_actions: ``NormalizeAndClipActions``'s ``normalize_actions``, or None where it is not recorded.
    """

    env_to_module: Any
    input_observation_space: Any
    input_action_space: Any
    transforms: tuple[str, ...]
    normalize_actions: bool | None

    def initial_state(self, batch_size: int) -> EpisodeState:
        """Fresh (empty) episodes for ``batch_size`` new episodes."""
        from ray.rllib.env.single_agent_episode import SingleAgentEpisode

        # With the spaces, as RLlib's env runner makes them: frame stacking pads an episode's start from them.
        return EpisodeState(episodes=[SingleAgentEpisode(observation_space=self.input_observation_space,
                                                         action_space=self.input_action_space)
                                      for _ in range(batch_size)])

    def module_batch(self, module: Any, obs: Any, state: EpisodeState, *, explore: bool) -> dict[str, Any]:
        """Appends each episode's new observation (and its last action) and runs the env-to-module pipeline.

        Args:
            module: The RLModule the batch is for (the pipeline asks it for its initial state, statefulness).
            obs: The batch of observations, one row per episode of ``state`` (a nested structure of arrays).
            state: The episodes, extended in place.
            explore: RLlib's ``explore`` flag (False for greedy play, as RLlib's evaluation).

        Returns:
            The module's input batch (``OBS``, ``STATE_IN``...), with a time axis of 1 for stateful modules.
        """
        import tree

        for row, episode in enumerate(state.episodes):
            observation = tree.map_structure(lambda x, i=row: x[i], obs)
            if not episode.is_reset:
                episode.add_env_reset(observation=observation)
            else:
                episode.add_env_step(observation=observation, action=state.actions[row], reward=0.0,
                                     extra_model_outputs=None if state.extras is None else state.extras[row])
        try:
            return self.env_to_module(rl_module=module, batch={}, episodes=state.episodes, explore=explore,
                                      shared_data={}, metrics=None)
        except AgentError:
            raise
        except Exception as exc:  # noqa: BLE001 - a connector fails on a foreign observation in any way
            raise AgentError(f"the checkpoint's env-to-module pipeline failed on the observations "
                             f"({describe_exception(exc)})") from None


def load_pipelines(folder: Path, *, source: str) -> ConnectorPipelines:
    """Restores and checks the pipelines in ``folder`` (what :func:`pipelines_dir` found).

    Args:
        folder: The env runner's folder of an algorithm checkpoint.
        source: The checkpoint, for messages.

    Raises:
        AgentError: A pipeline that cannot be restored, or a connector that is refused (module docstring).
    """
    from ray.rllib.connectors.connector_pipeline_v2 import ConnectorPipelineV2

    label = f"rllib checkpoint {source!r}"
    restored = {}
    for name in (ENV_TO_MODULE_DIR, MODULE_TO_ENV_DIR):
        if not (folder / name).is_dir():
            continue
        try:
            restored[name] = ConnectorPipelineV2.from_checkpoint((folder / name).resolve())
        except Exception as exc:  # noqa: BLE001 - missing classes or corrupt state surface as many types
            raise AgentError(f"{label}: cannot restore its {name} ({describe_exception(exc)})") from None
    env_to_module = restored[ENV_TO_MODULE_DIR]
    transforms = tuple(_check_env_to_module(connector, label=label) for connector in env_to_module.connectors)
    env_to_module.connectors[:] = [_for_play(connector) for connector in env_to_module.connectors]
    normalize = None
    for connector in getattr(restored.get(MODULE_TO_ENV_DIR), "connectors", ()):
        name = type(connector).__name__
        if name == "ModuleToAgentUnmapping":
            raise AgentError(f"{label}: its module-to-env pipeline is multi-agent (ModuleToAgentUnmapping); only "
                             f"single-agent checkpoints can be played")
        if name not in DEFAULT_MODULE_TO_ENV:
            raise AgentError(f"{label}: module-to-env connector {name} is not supported (supported: RLlib's "
                             f"default pieces: {', '.join(sorted(DEFAULT_MODULE_TO_ENV))})")
        if name == "NormalizeAndClipActions":
            normalize = bool(connector.get_ctor_args_and_kwargs()[1].get("normalize_actions", True))
    return ConnectorPipelines(env_to_module=env_to_module,
                              input_observation_space=env_to_module.input_observation_space,
                              input_action_space=env_to_module.input_action_space,
                              transforms=tuple(t for t in transforms if t), normalize_actions=normalize)


def _check_env_to_module(connector: Any, *, label: str) -> str:
    """The class name of a transforming connector, "" for a default piece; AgentError for a refused one."""
    from ray.rllib.connectors.env_to_module.observation_preprocessor import SingleAgentObservationPreprocessor

    name = type(connector).__name__
    if name in DEFAULT_ENV_TO_MODULE:
        return ""
    if name == "AgentToModuleMapping":
        raise AgentError(f"{label}: its env-to-module pipeline is multi-agent (AgentToModuleMapping); only "
                         f"single-agent checkpoints can be played")
    kwargs = connector.get_ctor_args_and_kwargs()[1]
    if name == "PrevActionsPrevRewards" and kwargs.get("n_prev_rewards", 1):
        raise AgentError(f"{label}: env-to-module connector PrevActionsPrevRewards feeds the module its previous "
                         f"rewards (n_prev_rewards={kwargs.get('n_prev_rewards', 1)}), which an agent is never "
                         f"told; it cannot be played")
    if name in SUPPORTED_ENV_TO_MODULE or isinstance(connector, SingleAgentObservationPreprocessor):
        return name
    raise AgentError(f"{label}: env-to-module connector {name} is not supported (supported: "
                     f"{', '.join(SUPPORTED_ENV_TO_MODULE)} and RLlib's default pieces)")


def _for_play(connector: Any) -> Any:
    """The connector as inference needs it: statistics frozen, tensors on the CPU where the module is."""
    name = type(connector).__name__
    if name == "MeanStdFilter":
        return _rebuilt(connector, update_stats=False)
    if name == "NumpyToTensor":
        return _rebuilt(connector, device=None, pin_memory=False)
    return connector


def _rebuilt(connector: Any, **overrides: Any) -> Any:
    """A new connector of the same class and constructor arguments but ``overrides``, with the same state."""
    _, kwargs = connector.get_ctor_args_and_kwargs()
    kwargs = {key: value for key, value in kwargs.items()
              if key not in ("input_observation_space", "input_action_space")}
    fresh = type(connector)(**{**kwargs, **overrides})
    # The spaces after construction, through their setters: some connectors (MeanStdFilter) compute their output
    # space from attributes their constructor sets only after the base class's.
    fresh.input_action_space = connector.input_action_space
    fresh.input_observation_space = connector.input_observation_space
    fresh.set_state(connector.get_state())
    return fresh
