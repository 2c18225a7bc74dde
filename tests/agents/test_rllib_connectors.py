"""``rllib:`` algorithm checkpoints played behind their connector pipelines (dsage_ray.agents.rllib_connectors).

The trained checkpoint, ``tests/fixtures/rllib_meanstd_cartpole/``, is a PPO on CartPole-v1 behind RLlib's
``MeanStdFilter``, trained by ``tests/fixtures/train_meanstd_ppo.py`` (which also recorded RLlib's own greedy
evaluation in ``evaluation.json``). The other checkpoints are assembled here from RLlib's own classes: a module saved
beside hand-built pipelines, in an algorithm checkpoint's layout.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import torch

from ray.rllib.connectors.connector_v2 import ConnectorV2
from ray.rllib.connectors.env_to_module.observation_preprocessor import SingleAgentObservationPreprocessor

from dsage_ray.agents import AgentError, load_agent
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.agents.rllib import MODULES_SUBDIR, RLlibAgent
from dsage_ray.agents.rllib_connectors import (ENV_RUNNER_DIR, ENV_TO_MODULE_DIR, MODULE_TO_ENV_DIR, EpisodeState,
                                               load_pipelines, pipelines_dir)
from dsage_ray.agents.rllib_module import MAZE_ACTION_SPACE, MAZE_OBSERVATION_SPACE, MazeRLModule
from dsage_ray.domains.gym.simulator import run_episodes
from dsage_ray.domains.gym.space import build_space

from tests.agents.conftest import REPO_ROOT

TRAINED = REPO_ROOT / "tests" / "fixtures" / "rllib_meanstd_cartpole"
#: The same checkpoint's bare module: the test-only way to play it without its pipeline.
TRAINED_MODULE = TRAINED / MODULES_SUBDIR / "default_policy"
CARTPOLE = gym.make("CartPole-v1")
#: CartPole-v1 with its default physics: one parameter, played at its default value (0.5 m).
CARTPOLE_SPACE = build_space({"env": {"id": "CartPole-v1"},
                              "params": {"length": {"range": [0.25, 2.0], "attr": "length"}},
                              "success": {"return_at_least": 475.0}})
NOMINAL = {"length": 0.5}
EPISODES = 20


def cartpole_agent(spec: str):
    return load_agent(spec, observation_space=CARTPOLE.observation_space, action_space=CARTPOLE.action_space)


def mean_return(spec: str, *, seeds=(0, 1)) -> float:
    agent = cartpole_agent(spec)
    return float(np.mean([run_episodes(CARTPOLE_SPACE, agent, NOMINAL, seed=s, episodes=EPISODES).returns.mean()
                          for s in seeds]))


def one_line_error(load) -> str:
    with pytest.raises(AgentError) as info:
        load()
    message = str(info.value)
    assert "\n" not in message
    return message


def save_checkpoint(folder, module, env_to_module: list, module_to_env: list | None = None):
    """An algorithm checkpoint's layout: the module under the learner, pipelines under the env runner."""
    from ray.rllib.connectors.common import (AddObservationsFromEpisodesToBatch, AddStatesFromEpisodesToBatch,
                                             AddTimeDimToBatchAndZeroPad, BatchIndividualItems, NumpyToTensor)
    from ray.rllib.connectors.env_to_module import EnvToModulePipeline
    from ray.rllib.connectors.module_to_env import ModuleToEnvPipeline

    module.save_to_path(str(folder / MODULES_SUBDIR / "default_policy"))
    # As AlgorithmConfig.build_env_to_module_connector builds it: the user's pieces, then RLlib's defaults.
    pipeline = EnvToModulePipeline(input_observation_space=module.observation_space if not env_to_module else
                                   env_to_module[0].input_observation_space,
                                   input_action_space=module.action_space,
                                   connectors=[*env_to_module, AddObservationsFromEpisodesToBatch(),
                                               AddTimeDimToBatchAndZeroPad(), AddStatesFromEpisodesToBatch(),
                                               BatchIndividualItems(), NumpyToTensor()])
    # With its state given, as the env runner saves it (a pipeline's own save trips over stateless pieces).
    pipeline.save_to_path(str(folder / ENV_RUNNER_DIR / ENV_TO_MODULE_DIR), state=pipeline.get_state())
    if module_to_env is not None:
        back = ModuleToEnvPipeline(connectors=module_to_env)
        back.save_to_path(str(folder / ENV_RUNNER_DIR / MODULE_TO_ENV_DIR), state=back.get_state())
    return folder


class ActionNoise(ConnectorV2):
    """A user's own module-to-env connector: the agents do not know what it does, so they refuse it."""

    def __call__(self, *, rl_module, batch, episodes, **kwargs):
        return batch


class Unchanged(SingleAgentObservationPreprocessor):
    """A user's observation transform (RLlib's API for one): here the identity, to compare with the direct path."""

    def recompute_output_observation_space(self, input_observation_space, input_action_space):
        return input_observation_space

    def preprocess(self, observation, episode):
        return observation


def identity_filter(space):
    """A MeanStdFilter that changes nothing (no de-meaning, no scaling, no clipping in range)."""
    from ray.rllib.connectors.env_to_module import MeanStdFilter

    connector = MeanStdFilter(de_mean_to_zero=False, de_std_to_one=False, clip_by_value=1e6)
    connector.input_observation_space = space
    return connector


# --- the trained MeanStdFilter checkpoint ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def returns():
    """Greedy mean returns on CartPole's default physics, with and without the pipeline; RLlib's own figure."""
    recorded = json.loads((TRAINED / "evaluation.json").read_text())
    assert recorded["explore"] is False and recorded["env"] == "CartPole-v1"
    return {"rllib": recorded["evaluation_return_mean"],
            "with": mean_return(f"rllib:{TRAINED}?greedy=1"),
            "without": mean_return(f"rllib:{TRAINED_MODULE}?greedy=1")}


def test_trained_checkpoint_is_played_behind_its_meanstd_filter():
    agent = cartpole_agent(f"rllib:{TRAINED}")
    assert agent.pipelines is not None and agent.pipelines.transforms == ("MeanStdFilter",)
    assert cartpole_agent(f"rllib:{TRAINED_MODULE}").pipelines is None


def test_played_with_its_pipeline_it_matches_rllibs_own_evaluation(returns):
    # RLlib's greedy evaluation played 20 episodes; ours 2 x 20 on other reset seeds.
    assert returns["with"] == pytest.approx(returns["rllib"], rel=0.1), returns


def test_played_without_its_pipeline_it_does_measurably_worse(returns):
    assert returns["without"] < 0.6 * returns["rllib"], returns
    assert returns["with"] - returns["without"] > 100, returns


def test_the_filter_is_frozen_at_its_saved_statistics_and_each_row_its_own():
    from ray.rllib.connectors.connector_pipeline_v2 import ConnectorPipelineV2
    from ray.rllib.core.rl_module import RLModule
    from ray.rllib.utils.filter import RunningStat

    pipelines = load_pipelines(pipelines_dir(TRAINED), source=str(TRAINED))
    module = RLModule.from_checkpoint(TRAINED_MODULE.resolve())
    saved = ConnectorPipelineV2.from_checkpoint((TRAINED / ENV_RUNNER_DIR / ENV_TO_MODULE_DIR).resolve())
    running = RunningStat.from_state(saved.get_state()["MeanStdFilter"][None]["running_stats"][0])
    assert running.n > 1000  # statistics of the training run, not of a fresh filter
    obs = np.random.default_rng(0).normal(size=(3, 4)).astype(np.float32) * np.float32([1, 1, 0.1, 1])
    expected = np.clip((obs - running.mean) / (running.std + 1e-8), -10, 10)

    state = pipelines.initial_state(3)
    first = pipelines.module_batch(module, obs, state, explore=False)["obs"].numpy()
    np.testing.assert_allclose(first, expected, rtol=1e-4, atol=1e-5)
    state = state.acted(np.array([0, 1, 0]))
    again = pipelines.module_batch(module, obs, state, explore=False)["obs"].numpy()
    np.testing.assert_array_equal(again, first)  # playing moved no statistic
    alone = pipelines.module_batch(module, obs[1:2], pipelines.initial_state(1), explore=False)["obs"].numpy()
    np.testing.assert_array_equal(alone[0], first[1])  # a row's input does not depend on the batch


# --- assembled checkpoints --------------------------------------------------------------------------------------


def default_module(observation_space, action_space, **model_config):
    from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    torch.manual_seed(0)
    return RLModuleSpec(module_class=DefaultPPOTorchRLModule, observation_space=observation_space,
                        action_space=action_space, model_config={"fcnet_hiddens": [8], **model_config}).build()


def test_frame_stacking_sees_each_episodes_own_frames_after_others_end(tmp_path):
    from ray.rllib.connectors.env_to_module.frame_stacking import FrameStackingEnvToModule

    frames_space = gym.spaces.Box(-np.inf, np.inf, (4, 4, 1), np.float32)  # RLlib stacks (w, h, 1) frames
    stack = FrameStackingEnvToModule(num_frames=3)
    stack.input_observation_space = frames_space
    module = default_module(stack.observation_space, CARTPOLE.action_space, conv_filters=[[4, 4, 1]])
    folder = save_checkpoint(tmp_path / "ckpt", module, [stack])
    agent = load_agent(f"rllib:{folder}?greedy=1", observation_space=frames_space,
                           action_space=CARTPOLE.action_space)
    pipelines = agent.pipelines
    assert pipelines.transforms == ("FrameStacking",)

    # frame[episode][t]: distinct numbers per episode and step; episode 0 ends after step 1.
    frame = {e: {t: np.full((4, 4, 1), 10 * e + t + 1, np.float32) for t in range(4)} for e in range(3)}
    running = [0, 1, 2]
    state = agent.initial_state(3)
    for t in range(4):
        if t == 2:
            running, state = [1, 2], agent.select_state(state, np.array([1, 2]))
        obs = np.stack([frame[e][t] for e in running])
        inputs = pipelines.module_batch(agent.module, obs, state, explore=False)["obs"].numpy()
        for row, e in enumerate(running):
            # RLlib's stacking: the last 3 frames on the last axis, zeros before the episode began.
            stacked = np.concatenate([frame[e][k] if k >= 0 else np.zeros((4, 4, 1), np.float32)
                                      for k in (t - 2, t - 1, t)], axis=2)
            np.testing.assert_array_equal(inputs[row], stacked)
        state = state.acted(np.zeros(len(running), dtype=np.int64))


def test_flattening_one_hots_and_concatenates_a_dict_observation(tmp_path):
    from ray.rllib.connectors.env_to_module import FlattenObservations

    observations = gym.spaces.Dict({"position": gym.spaces.Box(-1.0, 1.0, (2,), np.float32),
                                    "room": gym.spaces.Discrete(3)})
    flatten = FlattenObservations()
    flatten.input_observation_space = observations
    module = default_module(flatten.observation_space, CARTPOLE.action_space)
    folder = save_checkpoint(tmp_path / "ckpt", module, [flatten])
    agent = load_agent(f"rllib:{folder}", observation_space=observations, action_space=CARTPOLE.action_space)
    obs = {"position": np.float32([[0.5, -0.25], [0.0, 1.0]]), "room": np.array([2, 0])}
    inputs = agent.pipelines.module_batch(agent.module, obs, agent.initial_state(2), explore=True)
    # gymnasium's Dict keys are sorted: position, then room one-hot.
    np.testing.assert_array_equal(inputs["obs"].numpy(), np.float32([[0.5, -0.25, 0, 0, 1], [0, 1, 1, 0, 0]]))
    actions, _ = agent.act(obs, agent.initial_state(2), np.random.default_rng(0))
    assert actions.shape == (2,)


def test_recurrent_maze_module_behind_a_pipeline_acts_as_the_direct_path(tmp_path):
    torch.manual_seed(0)
    module = MazeRLModule(observation_space=MAZE_OBSERVATION_SPACE, action_space=MAZE_ACTION_SPACE,
                          model_config={"hidden": 16, "use_lstm": True})
    unchanged = Unchanged()
    unchanged.input_observation_space = MAZE_OBSERVATION_SPACE
    folder = save_checkpoint(tmp_path / "ckpt", module, [unchanged])
    piped = load_maze_agent(f"rllib:{folder}?greedy=1")
    direct = load_maze_agent(f"rllib:{folder / MODULES_SUBDIR / 'default_policy'}?greedy=1")
    assert isinstance(piped, RLlibAgent) and piped.pipelines.transforms == ("Unchanged",)
    assert direct.pipelines is None
    sampler = MAZE_OBSERVATION_SPACE
    sampler.seed(0)
    piped_state, direct_state = piped.initial_state(4), direct.initial_state(4)
    for step in range(5):
        n = 4 if step < 2 else 3
        obs = {"image": np.stack([sampler["image"].sample() for _ in range(n)]),
               "direction": np.array([sampler["direction"].sample() for _ in range(n)], dtype=np.int64)}
        piped_logits, piped_state = piped.logits(obs, piped_state)
        direct_logits, direct_state = direct.logits(obs, direct_state)
        torch.testing.assert_close(piped_logits, direct_logits)  # the LSTM state lives in RLlib's episodes
        assert isinstance(piped_state, EpisodeState) and len(piped_state.episodes) == n
        piped_state = piped_state.acted(piped_logits.argmax(dim=-1).numpy())
        if step == 1:  # the first episode ends
            piped_state = piped.select_state(piped_state, np.array([1, 2, 3]))
            direct_state = direct.select_state(direct_state, np.array([1, 2, 3]))


def test_the_module_to_env_pipeline_gives_normalize_actions_its_default(tmp_path):
    from ray.rllib.connectors.module_to_env import GetActions, NormalizeAndClipActions

    box = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    observations = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    module = default_module(observations, box)
    folder = save_checkpoint(tmp_path / "ckpt", module, [identity_filter(observations)],
                             [GetActions(), NormalizeAndClipActions(normalize_actions=False, clip_actions=True)])

    def load(spec):
        return load_agent(spec, observation_space=observations, action_space=box)

    assert load(f"rllib:{folder}").normalize_actions is False
    assert load(f"rllib:{folder}?normalize_actions=1").normalize_actions is True


# --- refused ----------------------------------------------------------------------------------------------------


def test_a_filter_of_previous_rewards_is_refused_in_one_line(tmp_path):
    from ray.rllib.connectors.env_to_module import PrevActionsPrevRewards

    prev = PrevActionsPrevRewards(n_prev_actions=1, n_prev_rewards=1)
    prev.input_action_space = CARTPOLE.action_space
    prev.input_observation_space = CARTPOLE.observation_space
    module = default_module(CARTPOLE.observation_space, CARTPOLE.action_space)  # refused before it would act
    folder = save_checkpoint(tmp_path / "ckpt", module, [prev])
    message = one_line_error(lambda: cartpole_agent(f"rllib:{folder}"))
    assert "PrevActionsPrevRewards" in message and "rewards" in message


def test_a_connector_outside_the_supported_ones_is_refused_naming_it(tmp_path):
    from ray.rllib.connectors.module_to_env import GetActions

    module = default_module(CARTPOLE.observation_space, CARTPOLE.action_space)
    folder = save_checkpoint(tmp_path / "ckpt", module, [identity_filter(CARTPOLE.observation_space)],
                             [GetActions(), ActionNoise()])
    message = one_line_error(lambda: cartpole_agent(f"rllib:{folder}"))
    assert "module-to-env connector ActionNoise is not supported" in message


def test_pipelines_the_agent_cannot_read_are_refused_not_guessed(tmp_path):
    module = default_module(CARTPOLE.observation_space, CARTPOLE.action_space)
    folder = save_checkpoint(tmp_path / "ckpt", module, [identity_filter(CARTPOLE.observation_space)])
    (folder / ENV_RUNNER_DIR / ENV_TO_MODULE_DIR / "state.pkl").write_bytes(b"not a pickle")
    message = one_line_error(lambda: cartpole_agent(f"rllib:{folder}"))
    assert "cannot restore its env_to_module_connector" in message


def test_a_pipeline_for_another_observation_space_is_refused_naming_both(tmp_path):
    observations = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    module = default_module(observations, CARTPOLE.action_space)
    folder = save_checkpoint(tmp_path / "ckpt", module, [identity_filter(observations)])
    message = one_line_error(lambda: cartpole_agent(f"rllib:{folder}"))
    assert "observation space" in message and "(3,)" in message and "(4,)" in message
