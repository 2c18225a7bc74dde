"""``sb3:`` agents played as trained: a zoo run folder's preprocessing matches SB3's own pipeline step for step,
sb3-contrib saves load, and the RL Zoo's published agents (``../shared/models/rl_zoo``, when present) play their
nominal environment as their ``evaluations.npz`` says.

Models are untrained unless they come from the zoo: what is tested is that the observation a policy sees is the one
SB3's ``VecNormalize`` and ``VecFrameStack`` give it, not what it learned.
"""

from __future__ import annotations

import collections
import sys

import gymnasium as gym
import numpy as np
import pytest
import yaml

from benchmarks.zoo_nominal import play
from dsage_ray.agents.base import Agent, AgentError
from dsage_ray.agents.rl_zoo import read_zoo_yaml
from dsage_ray.agents.spaces import stack_observations
from dsage_ray.agents import load_agent
from tests.agents.conftest import shared_dir

sb3 = pytest.importorskip("stable_baselines3")
from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack, VecNormalize  # noqa: E402

ZOO = shared_dir() / "models" / "rl_zoo"
needs_zoo = pytest.mark.skipif(not ZOO.is_dir(), reason=f"the RL Zoo agents are read from {ZOO} (not present)")


#: The env_wrapper entries the zoo writes (Gymnasium's own, and sb3-contrib's that its MuJoCo agents use), and the
#: wrapper itself, to build the reference pipeline with.
WRAPPERS = {"gymnasium.wrappers.TimeAwareObservation": lambda env: gym.wrappers.TimeAwareObservation(env),
            "sb3_contrib.common.wrappers.TimeFeatureWrapper": lambda env: _time_feature(env)}


def _time_feature(env: gym.Env) -> gym.Env:
    from sb3_contrib.common.wrappers import TimeFeatureWrapper

    return TimeFeatureWrapper(env)


def wrapped_cartpole(wrapper: str = "gymnasium.wrappers.TimeAwareObservation") -> gym.Env:
    return WRAPPERS[wrapper](gym.make("CartPole-v1"))


def write_zoo_yaml(path, items: dict) -> None:
    """As the zoo writes it: PyYAML's dump of an OrderedDict (the ``!!python/object/apply`` tag)."""
    path.write_text(yaml.dump(collections.OrderedDict(items)))


def make_run_folder(root, *, frame_stack: int = 2, wrapper: str = "gymnasium.wrappers.TimeAwareObservation"):
    """A zoo run folder of an untrained PPO behind a wrapper, VecNormalize (with statistics) and frame stacking."""
    folder = root / "ppo" / "CartPole-v1_1"
    config_dir = folder / "CartPole-v1"
    config_dir.mkdir(parents=True)
    venv = VecNormalize(DummyVecEnv([lambda: wrapped_cartpole(wrapper)]), norm_reward=True, clip_obs=5.0)
    venv.seed(0)
    venv.reset()
    for _ in range(200):  # statistics far from (0, 1), so that forgetting them shows
        venv.step(np.array([venv.action_space.sample()]))
    venv.obs_rms.mean += 3.0
    venv.obs_rms.var *= 4.0
    model = sb3.PPO("MlpPolicy", VecFrameStack(venv, frame_stack), n_steps=64, batch_size=32,
                    policy_kwargs={"net_arch": [8]}, device="cpu", seed=0)
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(sys.modules, "gym", None)  # SB3's save() probes legacy gym; the tests' own `gym` package fools it
        model.save(folder / "CartPole-v1.zip")
    venv.save(config_dir / "vecnormalize.pkl")
    write_zoo_yaml(config_dir / "config.yml", {"n_envs": 1, "normalize": True, "frame_stack": frame_stack,
                                               "env_wrapper": [wrapper], "policy": "MlpPolicy"})
    write_zoo_yaml(config_dir / "args.yml", {"algo": "ppo", "env": "CartPole-v1"})
    np.savez(folder / "evaluations.npz", timesteps=np.array([100, 200]), results=np.array([[10.0, 12.0], [50.0, 54.0]]),
             ep_lengths=np.array([[10, 12], [50, 54]]))
    return folder


@pytest.fixture(scope="module", params=list(WRAPPERS))
def run_folder(tmp_path_factory, request):
    if request.param.startswith("sb3_contrib"):
        pytest.importorskip("sb3_contrib")
    return make_run_folder(tmp_path_factory.mktemp("zoo"), wrapper=request.param)


class Recorder(Agent):
    """Stands in for the policy: records the observations it is given, acts 0."""

    def __init__(self):
        self.seen = []

    def initial_state(self, batch_size):
        return None

    def act(self, obs, state, rng):
        self.seen.append(np.array(obs))
        return np.zeros(len(obs), np.int64), None


def load_cartpole(spec: str) -> Agent:
    env = gym.make("CartPole-v1")
    return load_agent(spec, observation_space=env.observation_space, action_space=env.action_space, env=env)


def test_a_run_folder_sees_what_sb3s_pipeline_gives_its_policy_step_for_step(run_folder):
    wrapper = read_zoo_yaml(run_folder / "CartPole-v1" / "config.yml", label="")["env_wrapper"][0]
    agent = load_cartpole(f"sb3:{run_folder}")
    assert agent.expected_return == 52.0 and agent.expected_return_source.endswith("evaluations.npz")
    inner = agent.policy
    recorder = agent.policy = Recorder()
    reference = VecFrameStack(VecNormalize.load(str(run_folder / "CartPole-v1" / "vecnormalize.pkl"),
                                                DummyVecEnv([lambda: wrapped_cartpole(wrapper)])), 2)
    reference.venv.training = False
    reference.seed(7)
    expected = reference.reset()
    env = agent.wrap_env(gym.make("CartPole-v1"))
    obs, _ = env.reset(seed=7)
    state = agent.initial_state(1)
    rng = np.random.default_rng(0)
    for _ in range(30):
        _, state = agent.act(stack_observations([obs], env.observation_space), state, rng)
        np.testing.assert_allclose(recorder.seen[-1], expected, rtol=1e-5, atol=1e-5)
        action = inner.act(expected.astype(np.float32), None, rng)[0]
        expected, _, done, _ = reference.step(action)
        obs, _, terminated, truncated, _ = env.step(int(action[0]))
        if done[0] or terminated or truncated:
            break
    assert len(recorder.seen) > 5
    assert np.abs(recorder.seen[-1]).max() > 0.5  # normalised observations, not all zeros


def test_a_run_folder_is_played_deterministically_as_the_zoo_does_unless_told(run_folder):
    agent = load_cartpole(f"sb3:{run_folder}")
    assert agent.policy.greedy is True
    assert load_cartpole(f"sb3:{run_folder}?greedy=0").policy.greedy is False
    with pytest.raises(AgentError, match=r"observation space .*\(10,\).* does not match the environment's .*\(4,\)"):
        load_cartpole(f"sb3:{run_folder / 'CartPole-v1.zip'}")  # the save alone, without its wrapper and stacking


def test_finished_episodes_leave_the_stack_with_their_frames(run_folder):
    agent = load_cartpole(f"sb3:{run_folder}")
    agent.policy = Recorder()
    state = agent.initial_state(3)
    obs = np.arange(15, dtype=np.float32).reshape(3, 5)
    _, state = agent.act(obs, state, np.random.default_rng(0))
    kept = agent.select_state(state, np.array([0, 2]))
    _, kept = agent.act(obs[[0, 2]], kept, np.random.default_rng(0))
    first, second = agent.policy.seen
    np.testing.assert_array_equal(second[:, :5], first[[0, 2], 5:])  # the previous frame moved left, per episode


@pytest.mark.parametrize("edit, problem", [
    ({"env_wrapper": ["rl_zoo3.wrappers.FrameSkip"]}, "env_wrapper 'rl_zoo3.wrappers.FrameSkip' is neither"),
    ({"vec_env_wrapper": "rl_zoo3.vec_env_wrappers.X"}, "vec_env_wrapper"),
    ({"frame_stack": "four"}, "frame_stack 'four' is not a positive integer"),
    ({"normalize": "{'norm_obs': __import__('os')}"}, "normalize"),
])
def test_what_cannot_be_played_as_trained_is_refused_in_one_line(tmp_path, edit, problem):
    folder = make_run_folder(tmp_path)
    config = folder / "CartPole-v1" / "config.yml"
    write_zoo_yaml(config, {"normalize": True, "frame_stack": 2, **edit})
    with pytest.raises(AgentError, match="sb3 run folder") as info:
        load_cartpole(f"sb3:{folder}")
    assert problem in str(info.value) and "\n" not in str(info.value)


def test_missing_statistics_and_a_folder_that_is_no_run_are_named(tmp_path):
    folder = make_run_folder(tmp_path)
    (folder / "CartPole-v1" / "vecnormalize.pkl").unlink()
    with pytest.raises(AgentError, match="says normalize, but .*vecnormalize.pkl' is missing"):
        load_cartpole(f"sb3:{folder}")
    with pytest.raises(AgentError, match="not an RL Zoo run folder"):
        load_cartpole(f"sb3:{tmp_path}")


def test_sb3_contrib_saves_load(tmp_path):
    contrib = pytest.importorskip("sb3_contrib")
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(sys.modules, "gym", None)
        contrib.QRDQN("MlpPolicy", "CartPole-v1", buffer_size=10, policy_kwargs={"net_arch": [8]}, device="cpu",
                      seed=0).save(tmp_path / "qrdqn.zip")
        contrib.TQC("MlpPolicy", "Pendulum-v1", buffer_size=10, policy_kwargs={"net_arch": [8]}, device="cpu",
                    seed=0).save(tmp_path / "tqc.zip")
    assert type(load_cartpole(f"sb3:{tmp_path / 'qrdqn.zip'}").model).__name__ == "QRDQN"
    pendulum = gym.make("Pendulum-v1")
    tqc = load_agent(f"sb3:{tmp_path / 'tqc.zip'}", observation_space=pendulum.observation_space,
                         action_space=pendulum.action_space)
    assert type(tqc.model).__name__ == "TQC"
    actions = tqc.act(np.zeros((4, 3), np.float32), None, np.random.default_rng(0))[0]
    assert actions.shape == (4, 1) and np.all(np.abs(actions) <= 2.0)


# --- the RL Zoo's published agents ----------------------------------------------------------------------------


def nominal_returns(agent: Agent, env_id: str, episodes: int) -> np.ndarray:
    """Episodes of the environment as registered, side by side, as the simulators play them."""
    return play(agent, env_id, {}, episodes=episodes, seed=1000)


@needs_zoo
@pytest.mark.parametrize("folder", ["ppo/LunarLander-v2_1", "dqn/LunarLander-v2_1", "ppo/CartPole-v1_1",
                                    "ppo/BipedalWalker-v3_1"])
def test_every_zoo_folder_loads_with_its_expected_return(folder):
    env_id = {"LunarLander": "LunarLander-v3", "CartPole": "CartPole-v1", "BipedalWalker": "BipedalWalker-v3"}[
        folder.split("/")[1].split("-")[0]]
    env = gym.make(env_id)
    agent = load_agent(f"sb3:{ZOO / folder}", observation_space=env.observation_space,
                           action_space=env.action_space, env=env)
    assert agent.expected_return is not None and agent.expected_return > 100


@needs_zoo
def test_the_zoo_walker_walks_with_its_statistics_and_falls_without_them():
    folder = ZOO / "ppo" / "BipedalWalker-v3_1"
    with_stats = nominal_returns(load_walker(f"sb3:{folder}"), "BipedalWalker-v3", 4)
    without = nominal_returns(load_walker(f"sb3:{folder / 'BipedalWalker-v3.zip'}?greedy=1"), "BipedalWalker-v3", 4)
    assert np.median(with_stats) > 150 and without.max() < 0, (with_stats, without)


def load_walker(spec: str) -> Agent:
    env = gym.make("BipedalWalker-v3")
    return load_agent(spec, observation_space=env.observation_space, action_space=env.action_space, env=env)
