#!/usr/bin/env python3
"""Gymnasium oracle for red-mujoco's parity tests.

Reads one JSON object on stdin:

    {"env": "Hopper-v5", "kwargs": {...},
     "episodes": [{"qpos": [...], "qvel": [...], "actions": [[...], ...]}, ...]}

For each episode it resets the unwrapped Gymnasium environment (which runs
mj_resetData), sets qpos/qvel with `set_state`, records the observation, then
applies every action (as float64) with `step`, even past a termination (the
caller compares only up to where its own side terminated). Prints one JSON
object on stdout:

    {"versions": {...},
     "episodes": [{"obs": [...], "reset_info": {...}, "steps": [{"obs": [...], "reward": r,
                   "terminated": b, "info": {...}}, ...]}, ...]}

Non-finite numbers are written as null. Run it with the oracle virtualenv
made by scripts/setup-mujoco.sh: .venv-oracle/bin/python scripts/gym_oracle.py
"""

import json
import math
import sys
import warnings

import gymnasium
import mujoco
import numpy as np


def number(x):
    x = float(x)
    return x if math.isfinite(x) else None


def vector(a):
    return [number(v) for v in np.asarray(a, dtype=np.float64).ravel()]


def main():
    request = json.load(sys.stdin)
    warnings.simplefilter("ignore")
    env = gymnasium.make(request["env"], **request.get("kwargs", {})).unwrapped
    episodes = []
    for episode in request["episodes"]:
        env.reset(seed=0)
        qpos = np.array(episode["qpos"], dtype=np.float64)
        qvel = np.array(episode["qvel"], dtype=np.float64)
        env.set_state(qpos, qvel)
        reset_info = {k: number(v) for k, v in env._get_reset_info().items() if np.ndim(v) == 0}
        record = {"obs": vector(env._get_obs()), "reset_info": reset_info, "steps": []}
        for action in episode["actions"]:
            obs, reward, terminated, truncated, info = env.step(np.array(action, dtype=np.float64))
            record["steps"].append(
                {
                    "obs": vector(obs),
                    "reward": number(reward),
                    "terminated": bool(terminated),
                    "truncated": bool(truncated),
                    "info": {k: number(v) for k, v in info.items() if np.ndim(v) == 0},
                }
            )
        episodes.append(record)
    env.close()
    versions = {"gymnasium": gymnasium.__version__, "mujoco": mujoco.__version__, "numpy": np.__version__}
    json.dump({"versions": versions, "episodes": episodes}, sys.stdout)


if __name__ == "__main__":
    main()
