"""Gymnasium wrappers that replace the environment's reward with RED's.

The reward of a step is RED's reward of the pair (state the action was taken
in, action), the environment's own reward is kept in ``info["true_reward"]``
(red-core's ``RewardWrapper`` and imitation's ``RewardVecEnvWrapper`` do the
same). With a terminal heuristic, its penalty is added on the last step of an
episode (terminated or truncated), from that step's RED reward, as the
driving experiment does.
"""

from __future__ import annotations

from typing import Any, Optional

import gymnasium as gym
import numpy as np

from ._red import RedReward, TerminalHeuristic

TRUE_REWARD = "true_reward"


def _flat(x: Any) -> np.ndarray:
    return np.asarray(x, dtype=np.float64).reshape(1, -1)


class RedRewardWrapper(gym.Wrapper):
    """Single env: ``reward = r(s_t, a_t)`` (+ the terminal penalty at the
    end of an episode), ``info["true_reward"]`` = the env's reward."""

    def __init__(self, env: gym.Env, reward: RedReward, terminal: Optional[TerminalHeuristic] = None):
        super().__init__(env)
        self.red_reward = reward
        self.terminal = terminal
        self._last_obs: Optional[np.ndarray] = None

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._last_obs = _flat(obs)
        return obs, info

    def step(self, action):
        if self._last_obs is None:
            raise RuntimeError("RedRewardWrapper: call reset() before step()")
        obs, true_r, terminated, truncated, info = self.env.step(action)
        r = float(self.red_reward.reward(self._last_obs, _flat(action))[0])
        if self.terminal is not None and (terminated or truncated):
            r += self.terminal.penalty(r)
        self._last_obs = _flat(obs)
        info = dict(info)
        info[TRUE_REWARD] = float(true_r)
        return obs, r, terminated, truncated, info


# Gymnasium >= 1.0; imitation 1.0 pins Gymnasium 0.29, which has no
# VectorWrapper: there the single-env wrapper works and this one says so.
_VectorWrapper = getattr(gym.vector, "VectorWrapper", object)


class RedRewardVectorWrapper(_VectorWrapper):
    """Vector env: one batched reward call per step for all sub-envs.

    With Gymnasium's default autoreset (``NEXT_STEP``) the step after an
    episode's end only resets that sub-env: it has no state-action pair, and
    its reward stays the env's (0). With ``SAME_STEP`` every step is a real
    transition. ``info["true_reward"]`` holds the env's rewards (and
    ``info["_true_reward"]`` the mask, all True)."""

    def __init__(self, env: gym.vector.VectorEnv, reward: RedReward, terminal: Optional[TerminalHeuristic] = None):
        if _VectorWrapper is object:
            raise ImportError(
                f"RedRewardVectorWrapper needs gymnasium >= 1.0 (this is {gym.__version__}); wrap each "
                "sub-env in red.RedRewardWrapper instead (SB3: make_vec_env(..., wrapper_class=...))"
            )
        super().__init__(env)
        self.red_reward = reward
        self.terminal = terminal
        mode = env.metadata.get("autoreset_mode", gym.vector.AutoresetMode.NEXT_STEP)
        self._next_step_reset = mode in (gym.vector.AutoresetMode.NEXT_STEP, "NextStep", "next_step")
        self._last_obs: Optional[np.ndarray] = None
        self._resetting = np.zeros(self.num_envs, dtype=bool)

    def _rows(self, obs: Any) -> np.ndarray:
        return np.asarray(obs, dtype=np.float64).reshape(self.num_envs, -1)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._last_obs = self._rows(obs)
        self._resetting[:] = False
        return obs, info

    def step(self, actions):
        if self._last_obs is None:
            raise RuntimeError("RedRewardVectorWrapper: call reset() before step()")
        obs, true_r, terminated, truncated, info = self.env.step(actions)
        acts = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1)
        red = np.asarray(self.red_reward.reward(self._last_obs, acts))
        done = np.logical_or(terminated, truncated)
        if self.terminal is not None:
            red = red + np.where(done, [self.terminal.penalty(float(v)) for v in red], 0.0)
        true_r = np.asarray(true_r, dtype=np.float64)
        rewards = np.where(self._resetting, true_r, red) if self._next_step_reset else red
        self._resetting = done.copy() if self._next_step_reset else self._resetting
        self._last_obs = self._rows(obs)
        info = dict(info)
        info[TRUE_REWARD] = true_r
        info["_" + TRUE_REWARD] = np.ones(self.num_envs, dtype=bool)
        return obs, rewards, terminated, truncated, info
