"""The driving scenario (red-drive) as a Gymnasium environment.

``gymnasium.make("red/Drive-v0")`` builds it with the road's time limit
(``time_limit`` steps, Gymnasium's ``TimeLimit`` sets ``truncated``, as the
Rust ``make_env`` does with red-core's). Options: ``config`` (a dict of
``DriveConfig`` fields, missing ones take their defaults; a demo's
``scenario`` is one), ``render_mode="rgb_array"``.
"""

from __future__ import annotations

import json
from typing import Any, Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import _red

ENV_ID = "red/Drive-v0"


def default_config() -> dict:
    """The default road (``DriveConfig::default()``) as a dict."""
    return json.loads(_red.drive_default_config_json())


class DriveEnv(gym.Env):
    """A straight three-lane road with stopped cars, a car with steering and
    accelerator/brake in [-1, 1] at 20 Hz, and a 20-ray lidar.

    Observation: 24 float64 numbers (20 lidar ranges in [0, 1], lateral
    offset and heading error in [-1, 1], distance to the road edge and speed
    in [0, 1]). Action: float32 [steering, accelerator/brake] in [-1, 1]
    (out of range values are clipped by the car). Reward: metres gained
    along the road. ``terminated`` on a collision (info ``collision`` = 1)
    or at the end of the road (info ``success`` = 1). The episode has no
    time limit of its own: ``gymnasium.make`` adds one.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, config: Optional[dict] = None, render_mode: Optional[str] = None, render_width: int = 1600):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self._core = _red.DriveCore(None if config is None else json.dumps(config))
        self.config = json.loads(self._core.config_json())
        low, high = self._core.observation_bounds()
        self.observation_space = spaces.Box(
            low=np.asarray(low, dtype=np.float64), high=np.asarray(high, dtype=np.float64), dtype=np.float64
        )
        self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(_red.DRIVE_ACT_DIM,), dtype=np.float32)
        self.render_mode = render_mode
        self.render_width = render_width

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        """With ``seed`` the start noise restarts from it (the Rust env's
        ``reset(Some(seed))``); without one it continues its stream, seeded
        from Gymnasium's ``np_random`` on the first reset. ``options`` may
        hold ``start_observation``: start where a demonstration started
        (for replaying its actions)."""
        super().reset(seed=seed)
        if options and "start_observation" in options:
            obs = self._core.reset_to_observation(
                np.asarray(options["start_observation"], dtype=np.float64).tolist()
            )
            return obs, {}
        if seed is None and not getattr(self, "_seeded", False):
            # Gymnasium seeds np_random itself when no seed was ever given.
            seed = int(self.np_random.integers(0, 2**63 - 1))
        self._seeded = True
        obs, info = self._core.reset(None if seed is None else int(seed) % 2**64)
        return obs, info

    def step(self, action):
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        obs, reward, terminated, info = self._core.step(a.tolist())
        return obs, float(reward), bool(terminated), False, info

    def render(self):
        if self.render_mode == "rgb_array":
            return self._core.render_rgb(self.render_width)
        return None

    def expert_action(self) -> np.ndarray:
        """The scripted expert's action in the current state (it sees the
        road's true layout), float32."""
        return np.asarray(self._core.expert_action(), dtype=np.float32)

    def car_state(self) -> tuple:
        """(x, y, heading, speed) of the car."""
        return self._core.car()


def register() -> None:
    """Registers ``red/Drive-v0`` (done on ``import red``)."""
    if ENV_ID in gym.registry:
        return
    gym.register(
        id=ENV_ID,
        entry_point="red.envs:DriveEnv",
        max_episode_steps=default_config()["time_limit"],
    )


def make(config: Optional[dict] = None, **kwargs: Any) -> gym.Env:
    """``gymnasium.make("red/Drive-v0")`` with the time limit of ``config``'s
    road (its ``time_limit``)."""
    limit = json.loads(_red.DriveCore(None if config is None else json.dumps(config)).config_json())["time_limit"]
    return gym.make(ENV_ID, config=config, max_episode_steps=limit, **kwargs)
