"""Stable-Baselines3 agents (``sb3:PATH.zip``, ``sb3:RUN_FOLDER``), played as they were trained.

* ``sb3:PATH.zip``: a save of SB3 1.x (written under ``gym``) or 2.x, and of sb3-contrib (QR-DQN, TQC, TRPO, ARS;
  the ``sb3_contrib`` extra). The save is read as data (:mod:`dsage_ray.agents.sb3_files`): its spaces come from the
  environment (checked against the ones it recorded), its schedules are replaced, and SB3's loader is given every
  pickled entry so that it unpickles none.
* ``sb3:FOLDER``: an RL Baselines3 Zoo run folder (:mod:`dsage_ray.agents.rl_zoo`). What its ``config.yml`` says is
  applied: the ``env_wrapper`` around the environment, the ``VecNormalize`` observation statistics, ``frame_stack``
  (:class:`~dsage_ray.agents.preprocessing.TrainedAgent`); the agent carries the zoo's last evaluation as its
  :attr:`~dsage_ray.agents.base.Agent.expected_return`, which the audit's nominal check compares with.

Options: ``?algo=PPO`` (default: the zoo folder's, else read from the policy class) and ``?greedy=0|1``. Sampling
reads the policy's distribution and draws with the caller's ``rng``; greedy is SB3's ``predict(deterministic=True)``.
The default is sampling for a bare save; a zoo folder is played deterministically, as the zoo's ``enjoy.py`` plays it
and as its ``evaluations.npz`` was measured (Atari ones sampled, as ``enjoy.py`` does). Measured on the zoo's PPO
LunarLander-v2 played on v3, 20 episodes: 239.9 ± 6.3 deterministic, 155.5 ± 10.4 sampled, against the zoo's 249.8.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState
from dsage_ray.agents.loader import SpecOptions, describe_exception, local_path, require_file
from dsage_ray.agents.preprocessing import FrameStack, TrainedAgent
from dsage_ray.agents.rl_zoo import RunFolder, is_run_folder, read_run_folder
from dsage_ray.agents.sb3_files import Save, read_save, recorded_space
from dsage_ray.agents.spaces import check_space, finish_actions, gaussian, same_space, unsquash

#: The algorithms a save may be loaded as: ``NAME: (package, class)``.
ALGORITHMS: dict[str, tuple[str, str]] = {
    **{name: ("stable_baselines3", name) for name in ("PPO", "A2C", "DQN", "SAC", "TD3", "DDPG")},
    **{name: ("sb3_contrib", name) for name in ("QRDQN", "TQC", "TRPO", "ARS")},
}
#: Policy modules that name their algorithm (SB3 saves the policy class, not the algorithm).
_POLICY_MODULES = {"stable_baselines3.dqn.policies": "DQN", "stable_baselines3.sac.policies": "SAC",
                   "stable_baselines3.td3.policies": "TD3", "sb3_contrib.qrdqn.policies": "QRDQN",
                   "sb3_contrib.tqc.policies": "TQC", "sb3_contrib.ars.policies": "ARS"}


class SB3Agent(Agent):
    """A Stable-Baselines3 model; stateless. Sampling reads the policy's distribution and draws with ``rng``.

    Args:
        model: The loaded algorithm (``PPO.load(...)`` etc.).
        greedy: The policy's deterministic action (``predict(deterministic=True)``) instead of sampling.
    """

    def __init__(self, *, model: Any, greedy: bool = False) -> None:
        self.model = model
        self.policy = model.policy.eval()
        self.greedy = greedy

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        import torch

        space = self.policy.action_space
        if not self.greedy:
            obs_tensor, _ = self.policy.obs_to_tensor(obs)
            with torch.no_grad():
                dist = _distribution(self.policy, obs_tensor)
                if dist is not None:
                    actions = _sample(dist, rng)
                    if isinstance(space, spaces.Box) and self.policy.squash_output:
                        actions = unsquash(actions, space)
                    return finish_actions(actions, space), None
        # predict() does SB3's own preprocessing, unscaling and clipping: exactly the deterministic action.
        best, _ = self.policy.predict(obs, deterministic=True)
        return finish_actions(best if self.greedy else self._epsilon_greedy(best, rng), space), None

    def _epsilon_greedy(self, best: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """DQN's exploration (its ``predict(deterministic=False)``), per episode; TD3/DDPG have none (rate 0)."""
        rate = float(getattr(self.model, "exploration_rate", 0.0) or 0.0)
        space = self.policy.action_space
        if rate <= 0.0 or not isinstance(space, spaces.Discrete):
            return best
        explore = rng.random(len(best)) < rate
        return np.where(explore, space.start + rng.integers(0, space.n, size=len(best)), best)


def _distribution(policy: Any, obs_tensor: Any) -> Any:
    """The policy's action distribution (actor-critic or SAC-style actor), or None for value/deterministic ones."""
    if hasattr(policy, "get_distribution"):
        return policy.get_distribution(obs_tensor)
    actor = getattr(policy, "actor", None)
    if actor is not None and hasattr(actor, "get_action_dist_params"):
        mean, log_std, kwargs = actor.get_action_dist_params(obs_tensor)
        return actor.action_dist.proba_distribution(mean, log_std, **kwargs)
    return None


def _sample(dist: Any, rng: np.random.Generator) -> np.ndarray:
    """One draw per row from an SB3 distribution, with ``rng``."""
    from stable_baselines3.common import distributions as sb3_dist

    from dsage_ray.agents.sampling import sample_from_logits

    if isinstance(dist, sb3_dist.CategoricalDistribution):
        return sample_from_logits(dist.distribution.logits, rng)
    if isinstance(dist, sb3_dist.MultiCategoricalDistribution):
        return np.stack([sample_from_logits(part.logits, rng) for part in dist.distribution], axis=1)
    if isinstance(dist, sb3_dist.BernoulliDistribution):
        probs = dist.distribution.probs.double().numpy()
        return (rng.random(probs.shape) < probs).astype(np.int8)
    if isinstance(dist, sb3_dist.DiagGaussianDistribution):  # SquashedDiagGaussian (SAC) included
        normal = dist.distribution
        actions = gaussian(normal.mean.double().numpy(), normal.stddev.double().numpy(), greedy=False, rng=rng)
        return np.tanh(actions) if isinstance(dist, sb3_dist.SquashedDiagGaussianDistribution) else actions
    raise AgentError(f"sampling from SB3's {type(dist).__name__} is not supported (gSDE?); use ?greedy=1")


def algorithm_of(save: Save, *, label: str) -> str:
    """The algorithm that wrote ``save``, told from its policy class (and PPO/A2C/TRPO apart by their keys)."""
    module = save.policy_module
    if module == "stable_baselines3.common.policies":
        return "TRPO" if "cg_max_steps" in save.keys else "PPO" if "clip_range" in save.keys else "A2C"
    if module in _POLICY_MODULES:
        return _POLICY_MODULES[module]
    raise AgentError(f"{label}: cannot tell the algorithm from its policy class ({module or 'not recorded'}); "
                     f"name it with ?algo= ({', '.join(ALGORITHMS)})")


def _algorithm_class(algo: str, *, label: str) -> Any:
    package, name = ALGORITHMS[algo]
    try:
        return getattr(importlib.import_module(package), name)
    except ImportError:
        extra = "sb3_contrib" if package == "sb3_contrib" else "sb3"
        raise AgentError(f"{label}: {algo} agents need the {extra} extra: pip install 'dsage_ray[{extra}]'") from None


def _is_atari(env_id: str) -> bool:
    """The zoo's own test for the environments its ``enjoy.py`` samples in."""
    return "NoFrameskip" in env_id or env_id.startswith("ALE/")


def observation_fits(agent_space: Any, env_space: gymnasium.Space) -> bool:
    """Like :func:`same_space`, but SB3 models of channel-last images record (and transpose to) channel-first."""
    return same_space(agent_space, env_space) or _is_transposed_image(agent_space, env_space)


def _is_transposed_image(agent_space: Any, env_space: gymnasium.Space) -> bool:
    return (isinstance(agent_space, spaces.Box) and isinstance(env_space, spaces.Box) and len(env_space.shape) == 3
            and agent_space.shape == (env_space.shape[2], *env_space.shape[:2]))


def _channel_first(space: spaces.Box) -> spaces.Box:
    return spaces.Box(low=np.transpose(space.low, (2, 0, 1)), high=np.transpose(space.high, (2, 0, 1)),
                      dtype=space.dtype)


def load_sb3_agent(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
                   action_space: gymnasium.Space, env: Any = None) -> tuple[Agent, str]:
    """Loads ``sb3:TARGET`` (module docstring) against the environment's spaces.

    Args:
        target: A ``.zip`` save or a zoo run folder.
        options: ``algo`` and ``greedy``.
        observation_space, action_space: The environment's.
        env: The environment, needed where a zoo folder wraps it (its wrapped observation space is the policy's).

    Returns:
        The agent, and the label its errors carry.

    Raises:
        AgentError: What cannot be loaded or played as trained, in one line.
    """
    try:
        import stable_baselines3  # noqa: F401 - only to name the missing extra
    except ImportError:
        raise AgentError("sb3: agents need the sb3 extra: pip install 'dsage_ray[sb3]'") from None
    algo = options.get_str("algo", "").upper()
    folder = Path(local_path(target)).expanduser()
    run: RunFolder | None = None
    if folder.is_dir():
        label = f"sb3 run folder {str(folder)!r}"
        if not is_run_folder(folder):
            raise AgentError(f"{label}: not an RL Zoo run folder (ALGO/ENV_1 holding ENV.zip and ENV/config.yml)")
        run = read_run_folder(folder, label=label)
        path = run.model
    else:
        path = require_file(target, what="sb3 file")
        label = f"sb3 file {str(path)!r}"
    if algo and algo not in ALGORITHMS:
        raise AgentError(f"{label}: unknown ?algo={algo} (known: {', '.join(ALGORITHMS)})")
    save = read_save(path, label=label)
    algo = algo or (run.algo if run and run.algo in ALGORITHMS else "") or algorithm_of(save, label=label)
    greedy = options.get_bool("greedy", run is not None and not _is_atari(run.env_id))
    wrappers = run.env_wrappers(label=label) if run else []
    if wrappers:
        if env is None:
            raise AgentError(f"{label}: its env_wrapper needs the environment to be given to the loader")
        for wrapper in wrappers:  # once: a wrapper may change the environment it wraps (TimeFeatureWrapper does)
            env = wrapper(env)
        observation_space = env.observation_space
    stack = FrameStack(space=observation_space, n=run.frame_stack) if run and run.frame_stack > 1 else None
    policy_space = stack.space if stack else observation_space
    recorded_obs = recorded_space(save.data["observation_space"])
    check_space(recorded_obs, policy_space, which="observation", label=label, fits=observation_fits)
    check_space(recorded_space(save.data["action_space"]), action_space, which="action", label=label)
    if run and run.normalization and run.normalization.keys is None \
            and np.shape(run.normalization.mean) != observation_space.shape:
        raise AgentError(f"{label}: its VecNormalize statistics have shape {np.shape(run.normalization.mean)}, the "
                         f"observations {observation_space.shape}")
    given = _channel_first(policy_space) if _is_transposed_image(recorded_obs, policy_space) else policy_space
    custom = {**save.custom_objects, "observation_space": given, "action_space": action_space}
    try:
        model = _algorithm_class(algo, label=label).load(str(path), device="cpu", custom_objects=custom)
    except AgentError:
        raise
    except Exception as exc:  # noqa: BLE001 - a corrupt or foreign zip fails in any way
        raise AgentError(f"{label}: cannot load it as {algo} ({describe_exception(exc)})") from None
    agent: Agent = SB3Agent(model=model, greedy=greedy)
    if run is not None:
        agent = TrainedAgent(policy=agent, env_wrappers=wrappers, wrapped_space=observation_space,
                             normalization=run.normalization, frame_stack=stack)
        agent.expected_return = run.expected_return
        agent.expected_return_source = f"{folder.name}/evaluations.npz" if run.expected_return is not None else ""
    return agent, label
