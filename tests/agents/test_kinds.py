"""dsage_ray's own agent kinds over Gymnasium spaces (the gym domain's agents): every kind loads, acts in the environment's spaces, and fails in one line.

RLlib modules and SB3 models are built untrained (weights at random) and saved to temporary folders: loading
and acting is what is tested, not what they learned. No Ray cluster starts.
"""

from __future__ import annotations

import copy
import sys
import textwrap
import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch

from dsage_ray.agent_registry import BUILTIN_KINDS
from dsage_ray.agents import load_agent
from dsage_ray.agents.base import AgentError
from dsage_ray.agents.kinds import FORMS
from dsage_ray.agents.loader import KINDS_RUNNING_CODE
from dsage_ray.agents.rllib import RLlibAgent
from dsage_ray.agents.spaces import stack_observations

CARTPOLE_OBS = gym.spaces.Box(np.array([-4.8, -np.inf, -0.42, -np.inf], np.float32),
                              np.array([4.8, np.inf, 0.42, np.inf], np.float32), dtype=np.float32)
CARTPOLE_ACT = gym.spaces.Discrete(2)
LUNAR_OBS = gym.spaces.Box(-np.inf, np.inf, (8,), np.float32)
LUNAR_ACT = gym.spaces.Discrete(4)
PENDULUM_OBS = gym.spaces.Box(np.array([-1, -1, -8], np.float32), np.array([1, 1, 8], np.float32), dtype=np.float32)
PENDULUM_ACT = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)


def cartpole(spec: str, **kwargs):
    return load_agent(spec, observation_space=CARTPOLE_OBS, action_space=CARTPOLE_ACT, **kwargs)


def pendulum(spec: str):
    return load_agent(spec, observation_space=PENDULUM_OBS, action_space=PENDULUM_ACT)


def load_error(spec: str, observation_space=CARTPOLE_OBS, action_space=CARTPOLE_ACT) -> str:
    with pytest.raises(AgentError) as info:
        load_agent(spec, observation_space=observation_space, action_space=action_space)
    message = str(info.value)
    assert "\n" not in message and "Traceback" not in message
    return message


def batch(space: gym.Space, n: int, seed: int = 1):
    space = copy.deepcopy(space)  # seeding must not change the shared constants
    space.seed(seed)
    return stack_observations([space.sample() for _ in range(n)], space)


def act(agent, obs, seed: int = 0) -> np.ndarray:
    actions, _ = agent.act(obs, agent.initial_state(len(obs)), np.random.default_rng(seed))
    return actions


def assert_valid(actions: np.ndarray, space: gym.Space, n: int) -> None:
    assert isinstance(actions, np.ndarray) and actions.shape == (n, *space.shape)
    assert actions.dtype == (np.int64 if isinstance(space, gym.spaces.Discrete) else np.float32)
    assert all(space.contains(a) for a in actions)


# --- forms, batching ------------------------------------------------------------------------------------------


def test_every_kind_has_a_form_and_says_whether_loading_runs_code():
    assert set(FORMS) == set(BUILTIN_KINDS) == {"random", "rllib", "sb3", "torchscript", "qtable", "python"}
    runs_code = {kind: kind in KINDS_RUNNING_CODE for kind in FORMS}
    assert runs_code == {"random": False, "sb3": False, "qtable": False, "rllib": True, "torchscript": True,
                         "python": True}


def test_unknown_kind_lists_the_forms():
    message = load_error("dcd:accel")
    # The kinds' names (the one registry's), no longer the gym's own spec forms.
    assert "unknown kind 'dcd'" in message and "sb3" in message and "torchscript" in message


def test_stack_observations_box_discrete_dict_and_tuple():
    box = gym.spaces.Box(0, 255, (2, 3), np.uint8)
    stacked = stack_observations([np.full((2, 3), i) for i in range(4)], box)
    assert stacked.shape == (4, 2, 3) and stacked.dtype == np.uint8 and stacked[3, 1, 2] == 3
    discrete = stack_observations([np.int64(2), 0, 1], gym.spaces.Discrete(3))
    assert discrete.dtype == np.int64 and discrete.tolist() == [2, 0, 1]
    space = gym.spaces.Dict({"pos": gym.spaces.Box(-1, 1, (2,), np.float32), "dir": gym.spaces.Discrete(4)})
    stacked = stack_observations([{"pos": [0.5, -0.5], "dir": 3}, {"pos": [0.0, 1.0], "dir": 1}], space)
    assert stacked["pos"].shape == (2, 2) and stacked["pos"].dtype == np.float32 and stacked["dir"].tolist() == [3, 1]
    pair = stack_observations([(1, [0.0]), (0, [2.0])], gym.spaces.Tuple((gym.spaces.Discrete(2), PENDULUM_ACT)))
    assert isinstance(pair, tuple) and pair[0].tolist() == [1, 0] and pair[1].shape == (2, 1)
    assert stack_observations([], box).shape == (0, 2, 3)


# --- random ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("space", [CARTPOLE_ACT, PENDULUM_ACT, gym.spaces.Box(-np.inf, np.inf, (2, 2), np.float32),
                                   gym.spaces.MultiDiscrete([3, 2])], ids=str)
def test_random_agent_gives_valid_reproducible_actions(space):
    agent = load_agent("random", observation_space=CARTPOLE_OBS, action_space=space)
    obs = batch(CARTPOLE_OBS, 64)
    first = act(agent, obs, seed=3)
    assert first.shape == (64, *space.shape) and all(space.contains(a) for a in first)
    assert np.array_equal(first, act(agent, obs, seed=3))
    assert not np.array_equal(first, act(agent, obs, seed=4))
    assert agent.spec == "random"


# --- rllib ----------------------------------------------------------------------------------------------------


def save_rllib_module(folder, observation_space, action_space, **model_config):
    from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    torch.manual_seed(0)
    module = RLModuleSpec(module_class=DefaultPPOTorchRLModule, observation_space=observation_space,
                          action_space=action_space, model_config={"fcnet_hiddens": [16], **model_config}).build()
    module.save_to_path(str(folder))
    return folder


@pytest.fixture(scope="module")
def rllib_modules(tmp_path_factory):
    root = tmp_path_factory.mktemp("rllib")
    return {
        "cartpole": save_rllib_module(root / "cartpole", CARTPOLE_OBS, CARTPOLE_ACT),
        "lunar": save_rllib_module(root / "lunar", LUNAR_OBS, LUNAR_ACT),
        "pendulum": save_rllib_module(root / "pendulum", PENDULUM_OBS, PENDULUM_ACT),
        "lstm": save_rllib_module(root / "lstm", CARTPOLE_OBS, CARTPOLE_ACT, use_lstm=True, lstm_cell_size=8,
                                  max_seq_len=4),
    }


def test_rllib_discrete_samples_with_rng_and_greedy_is_deterministic(rllib_modules):
    agent = cartpole(f"rllib:{rllib_modules['cartpole']}")
    assert isinstance(agent, RLlibAgent)
    obs = batch(CARTPOLE_OBS, 200)
    sampled = act(agent, obs, seed=0)
    assert_valid(sampled, CARTPOLE_ACT, 200)
    assert np.array_equal(sampled, act(agent, obs, seed=0)) and not np.array_equal(sampled, act(agent, obs, seed=1))
    greedy = cartpole(f"rllib:{rllib_modules['cartpole']}?greedy=1")
    assert_valid(act(greedy, obs), CARTPOLE_ACT, 200)
    assert np.array_equal(act(greedy, obs, seed=0), act(greedy, obs, seed=1))


def test_rllib_module_of_other_spaces_is_refused_naming_both(rllib_modules):
    message = load_error(f"rllib:{rllib_modules['lunar']}")
    assert message.startswith(f"rllib checkpoint '{rllib_modules['lunar']}': observation space")
    assert "(8,)" in message and "(4,)" in message and "environment's" in message
    message = load_error(f"rllib:{rllib_modules['cartpole']}", action_space=LUNAR_ACT)
    assert "action space Discrete(2) does not match the environment's Discrete(4)" in message


def test_rllib_continuous_actions_lie_within_bounds(rllib_modules):
    agent = pendulum(f"rllib:{rllib_modules['pendulum']}")
    obs = batch(PENDULUM_OBS, 300)
    actions = act(agent, obs)
    assert_valid(actions, PENDULUM_ACT, 300)
    assert actions.min() == -2.0 and actions.max() == 2.0  # unit-std noise, unsquashed to [-2, 2], then clipped
    greedy = pendulum(f"rllib:{rllib_modules['pendulum']}?greedy=1&normalize_actions=0")
    mean = act(greedy, obs)
    assert_valid(mean, PENDULUM_ACT, 300) and np.array_equal(mean, act(greedy, obs, seed=9))
    assert np.abs(mean).max() < 2.0  # an untrained mean stays small: no clipping, no rescaling


def test_rllib_recurrent_module_carries_and_selects_state(rllib_modules):
    agent = cartpole(f"rllib:{rllib_modules['lstm']}")
    state = agent.initial_state(5)
    assert state["h"].shape == (5, 1, 8)
    obs = batch(CARTPOLE_OBS, 5)
    actions, state = agent.act(obs, state, np.random.default_rng(0))
    assert_valid(actions, CARTPOLE_ACT, 5) and state["h"].abs().sum() > 0
    kept = agent.select_state(state, np.array([0, 3]))
    actions, _ = agent.act(obs[[0, 3]], kept, np.random.default_rng(0))
    assert actions.shape == (2,)


def test_rllib_bad_targets_fail_in_one_line(tmp_path, rllib_modules):
    assert "not found" in load_error(f"rllib:{tmp_path / 'nope'}")
    assert "not an RLlib checkpoint" in load_error(f"rllib:{tmp_path}")
    assert "unknown option(s) sample" in load_error(f"rllib:{rllib_modules['cartpole']}?sample=1")
    message = load_error(f"rllib:{rllib_modules['pendulum']}", observation_space=PENDULUM_OBS,
                         action_space=gym.spaces.MultiDiscrete([2, 2]))
    assert "action space" in message


# --- sb3 ------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sb3_models(tmp_path_factory):
    sb3 = pytest.importorskip("stable_baselines3")
    root = tmp_path_factory.mktemp("sb3")
    with pytest.MonkeyPatch.context() as patch:
        # pytest imports this test folder as the top-level package `gym`; SB3's save() probes `gym.__version__`
        # (legacy OpenAI Gym) and fails on it, so make that import fail as it does outside the tests.
        patch.setitem(sys.modules, "gym", None)
        save_sb3_models(sb3, root)
    return root


def save_sb3_models(sb3, root):
    # A fresh policy_kwargs each: SB3 adds keys to the dict it is given (SAC's use_sde breaks DQN).
    sb3.PPO("MlpPolicy", "CartPole-v1", n_steps=64, batch_size=32, policy_kwargs={"net_arch": [16]}, device="cpu",
            seed=0).save(root / "ppo_cartpole.zip")
    sb3.SAC("MlpPolicy", "Pendulum-v1", buffer_size=10, policy_kwargs={"net_arch": [16]}, device="cpu",
            seed=0).save(root / "sac_pendulum.zip")
    sb3.DQN("MlpPolicy", "CartPole-v1", buffer_size=10, policy_kwargs={"net_arch": [16]}, device="cpu",
            seed=0).save(root / "dqn_cartpole.zip")


def test_sb3_ppo_reads_its_algorithm_samples_and_greedy(sb3_models):
    agent = cartpole(f"sb3:{sb3_models / 'ppo_cartpole.zip'}")
    assert type(agent.model).__name__ == "PPO"
    obs = batch(CARTPOLE_OBS, 200)
    sampled = act(agent, obs, seed=0)
    assert_valid(sampled, CARTPOLE_ACT, 200)
    assert np.array_equal(sampled, act(agent, obs, seed=0)) and not np.array_equal(sampled, act(agent, obs, seed=1))
    greedy = cartpole(f"sb3:{sb3_models / 'ppo_cartpole.zip'}?greedy=1&algo=ppo")
    expected, _ = greedy.model.predict(obs, deterministic=True)
    assert np.array_equal(act(greedy, obs, seed=5), expected)


def test_sb3_sac_and_dqn(sb3_models):
    sac = pendulum(f"sb3:{sb3_models / 'sac_pendulum.zip'}")
    assert type(sac.model).__name__ == "SAC"
    actions = act(sac, batch(PENDULUM_OBS, 100))
    assert_valid(actions, PENDULUM_ACT, 100) and actions.std() > 0.1  # tanh-squashed draws, rescaled to [-2, 2]
    dqn = cartpole(f"sb3:{sb3_models / 'dqn_cartpole.zip'}")
    assert type(dqn.model).__name__ == "DQN"
    assert_valid(act(dqn, batch(CARTPOLE_OBS, 50)), CARTPOLE_ACT, 50)


def test_sb3_bad_files_and_wrong_spaces_fail_in_one_line(tmp_path, sb3_models):
    not_zip = tmp_path / "policy.zip"
    not_zip.write_text("hello")
    assert "not a zip file" in load_error(f"sb3:{not_zip}")
    assert "file not found" in load_error(f"sb3:{tmp_path / 'missing.zip'}")
    assert "unknown ?algo=XYZ" in load_error(f"sb3:{sb3_models / 'ppo_cartpole.zip'}?algo=xyz")
    message = load_error(f"sb3:{sb3_models / 'ppo_cartpole.zip'}", observation_space=LUNAR_OBS, action_space=LUNAR_ACT)
    assert "observation space" in message and "(4,)" in message and "(8,)" in message


def test_sb3_missing_extra_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # makes the import fail
    assert load_error(f"sb3:{tmp_path / 'x.zip'}") == "sb3: agents need the sb3 extra: pip install 'dsage_ray[sb3]'"


# --- torchscript ----------------------------------------------------------------------------------------------


def script(tmp_path, name: str, module: torch.nn.Module):
    path = tmp_path / name
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # torch 2.9+ deprecates TorchScript
        torch.jit.script(module).save(str(path))
    return path


def test_torchscript_discrete_and_box(tmp_path):
    torch.manual_seed(0)
    agent = cartpole(f"torchscript:{script(tmp_path, 'cp.pt', torch.nn.Linear(4, 2))}")
    obs = batch(CARTPOLE_OBS, 100)
    assert_valid(act(agent, obs), CARTPOLE_ACT, 100)
    assert np.array_equal(act(agent, obs, seed=2), act(agent, obs, seed=2))
    scaled = torch.nn.Sequential(torch.nn.Linear(3, 1), torch.nn.Tanh())
    scaled[0].weight.data.fill_(0.0)
    scaled[0].bias.data.fill_(5.0)  # tanh(5) ~ 1: used as is, not rescaled
    actions = act(pendulum(f"torchscript:{script(tmp_path, 'pend.pt', scaled)}"), batch(PENDULUM_OBS, 3))
    assert_valid(actions, PENDULUM_ACT, 3) and np.allclose(actions, np.tanh(5.0))


def test_torchscript_wrong_output_or_file_is_refused(tmp_path):
    message = load_error(f"torchscript:{script(tmp_path, 'three.pt', torch.nn.Linear(4, 3))}")
    assert "three.pt" in message and "logits of shape (3,)" in message and "Discrete(2)" in message
    message = load_error(f"torchscript:{script(tmp_path, 'wide.pt', torch.nn.Linear(3, 2))}",
                         observation_space=PENDULUM_OBS, action_space=PENDULUM_ACT)
    assert "actions of shape (2,)" in message
    assert "failed" in load_error(f"torchscript:{script(tmp_path, 'in.pt', torch.nn.Linear(5, 2))}")
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not torchscript")
    assert "not a TorchScript module" in load_error(f"torchscript:{junk}")


# --- python ---------------------------------------------------------------------------------------------------


POLICY_SOURCE = textwrap.dedent("""
    import numpy as np

    def act(obs):
        return int(obs[2] > 0)  # push towards the pole's lean

    def noisy(obs, rng):
        return int(rng.integers(2))

    def wide(obs):
        return np.zeros(3)

    NOT_A_FUNCTION = 3
""")


@pytest.fixture()
def policy_file(tmp_path):
    path = tmp_path / "pol.py"
    path.write_text(POLICY_SOURCE)
    return path


def test_python_function_from_a_file(policy_file):
    path_before = list(sys.path)
    agent = cartpole(f"python:{policy_file}:act")
    assert sys.path == path_before
    obs = batch(CARTPOLE_OBS, 20)
    actions = act(agent, obs)
    assert_valid(actions, CARTPOLE_ACT, 20) and np.array_equal(actions, (obs[:, 2] > 0).astype(np.int64))
    noisy = cartpole(f"python:{policy_file}:noisy")
    assert np.array_equal(act(noisy, batch(CARTPOLE_OBS, 50), seed=1), act(noisy, batch(CARTPOLE_OBS, 50), seed=1))


def test_python_function_from_a_module(tmp_path, monkeypatch):
    (tmp_path / "gym_test_policy_mod.py").write_text(POLICY_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert_valid(act(cartpole("python:gym_test_policy_mod:act"), batch(CARTPOLE_OBS, 4)), CARTPOLE_ACT, 4)


def test_python_function_reads_a_text_observation_a_network_could_not(tmp_path):
    # MiniGrid's observation: an image, a direction and a mission string (a Text-like space).
    space = gym.spaces.Dict({"image": gym.spaces.Box(0, 10, (3, 3, 3), np.uint8), "direction": gym.spaces.Discrete(4),
                             "mission": gym.spaces.Text(max_length=20)})
    stacked = stack_observations([{"image": np.zeros((3, 3, 3)), "direction": 1, "mission": "go left"},
                                  {"image": np.ones((3, 3, 3)), "direction": 2, "mission": "go"}], space)
    assert stacked["mission"].dtype == object and stacked["mission"].tolist() == ["go left", "go"]
    assert stacked["image"].shape == (2, 3, 3, 3) and stacked["direction"].tolist() == [1, 2]
    (tmp_path / "reads.py").write_text("def act(obs):\n    return len(obs['mission']) % 2\n")
    agent = load_agent(f"python:{tmp_path / 'reads.py'}:act", observation_space=space, action_space=CARTPOLE_ACT)
    actions = agent.act(stacked, None, np.random.default_rng(0))[0]
    assert actions.tolist() == [1, 0]  # len('go left') is odd, len('go') even
    # A Sequence observation stays one object per row, even when every row has the same length.
    row = (np.zeros(2, np.float32), np.ones(2, np.float32))
    sequences = stack_observations([row, row, row], gym.spaces.Sequence(gym.spaces.Box(0, 1, (2,))))
    assert sequences.shape == (3,) and sequences[2] is row


def test_python_errors_name_the_spec(policy_file, tmp_path):
    assert "has no function 'nope'" in load_error(f"python:{policy_file}:nope")
    assert "not callable" in load_error(f"python:{policy_file}:NOT_A_FUNCTION")
    assert "module 'no_such_policy_module' not found" in load_error("python:no_such_policy_module:act")
    assert "file not found" in load_error(f"python:{tmp_path / 'missing.py'}:act")
    assert "expected python:MODULE:FUNCTION" in load_error("python:just_a_module")
    message = load_error(f"python:{policy_file}:wide")
    assert message.startswith(f"python policy '{policy_file}:wide'") and "shape (3,)" in message
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('boom')\n")
    assert "RuntimeError: boom" in load_error(f"python:{broken}:act")
