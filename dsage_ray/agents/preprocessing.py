"""An agent played with the preprocessing it was trained with: environment wrappers, observation statistics, stacking.

RL libraries put preprocessing between the environment and the policy (SB3's ``VecNormalize`` and ``VecFrameStack``,
the zoo's ``env_wrapper``). :class:`TrainedAgent` wraps a policy with the same steps, in the zoo's order: the
environment wrappers (applied by the simulator through :meth:`Agent.wrap_env`), then the observation statistics
(frozen, as at evaluation time), then frame stacking, whose frames live in the agent state so that each episode keeps
its own and a finished episode's leave the batch with it.
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState
from dsage_ray.agents.rl_zoo import EnvWrapper
from dsage_ray.agents.sb3_files import ObservationStats


class FrameStack:
    """SB3's ``VecFrameStack`` over a Box observation: the last ``n`` observations, concatenated on the channel axis.

    Args:
        space: The observation space of one frame.
        n: Frames stacked.
    """

    def __init__(self, *, space: gymnasium.Space, n: int) -> None:
        from stable_baselines3.common.vec_env.stacked_observations import StackedObservations

        if not isinstance(space, spaces.Box):
            raise AgentError(f"frame_stack is supported for Box observations, not {space}")
        self.n = n
        self.frame_space = space
        # SB3's own rule for which axis holds channels, so the stack is laid out as in training.
        # (axis counts the batch axis, as SB3's does)
        _, self.axis, _, repeat_axis = StackedObservations.compute_stacking(n, space)
        self.space = spaces.Box(low=np.repeat(space.low, n, axis=repeat_axis),
                                high=np.repeat(space.high, n, axis=repeat_axis), dtype=space.dtype)
        self._width = space.shape[repeat_axis]

    def initial(self, batch_size: int) -> np.ndarray:
        return np.zeros((batch_size, *self.space.shape), dtype=self.space.dtype)

    def push(self, frames: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """The stack after one more observation: the oldest frame drops out (a new episode's stack starts at zero)."""
        frames = np.roll(frames, shift=-self._width, axis=self.axis)
        index = [slice(None)] * frames.ndim
        index[self.axis] = slice(-self._width, None)
        frames[tuple(index)] = obs
        return frames


class TrainedAgent(Agent):
    """``policy`` behind its training-time preprocessing (module docstring).

    Args:
        policy: The agent that acts on preprocessed observations.
        env_wrappers: ``wrapper(env) -> env`` in the order they were applied in training.
        wrapped_space: The observation space of an environment inside ``env_wrappers`` (with wrappers).
        normalization: Observation statistics applied before stacking, or None.
        frame_stack: Frame stacking after normalisation, or None.
    """

    def __init__(self, *, policy: Agent, env_wrappers: Sequence[EnvWrapper] = (), wrapped_space: Any = None,
                 normalization: ObservationStats | None = None, frame_stack: FrameStack | None = None) -> None:
        self.policy = policy
        self.env_wrappers = tuple(env_wrappers)
        self.wrapped_space = wrapped_space
        self.normalization = normalization
        self.frame_stack = frame_stack

    def wrap_env(self, env: Any) -> Any:
        for wrapper in self.env_wrappers:
            env = wrapper(env)
        return env

    def observed_space(self, env_space: Any) -> Any:
        return self.wrapped_space if self.env_wrappers else env_space

    def initial_state(self, batch_size: int) -> AgentState:
        frames = self.frame_stack.initial(batch_size) if self.frame_stack else None
        return frames, self.policy.initial_state(batch_size)

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        frames, inner = state
        if self.normalization is not None:
            obs = self.normalization.apply(obs)
        if self.frame_stack is not None:
            frames = self.frame_stack.push(frames, obs)
            obs = frames
        actions, inner = self.policy.act(obs, inner, rng)
        return actions, (frames, inner)

    def select_state(self, state: AgentState, index: np.ndarray) -> AgentState:
        frames, inner = state
        return (None if frames is None else frames[index]), self.policy.select_state(inner, index)
