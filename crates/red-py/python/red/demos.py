"""The project's demonstration files (red-core's versioned JSON format).

Reading and writing go through the Rust code (``red-core``'s ``Demos``), which
validates everything (dimensions, finite numbers, non-empty trajectories) and
names the trajectory and step of the first problem. Python holds the data as
numpy arrays.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, List, Optional

import numpy as np

from . import _red


@dataclass
class Trajectory:
    """One demonstrated episode.

    ``observations[t]`` (T, obs_dim) is the state in which ``actions[t]``
    (T, act_dim) was taken; ``rewards`` (T,) are the environment's true
    rewards when known; ``terminated`` is True when the task ended the
    episode, False when a time limit cut it.
    """

    observations: np.ndarray
    actions: np.ndarray
    rewards: Optional[np.ndarray] = None
    terminated: bool = True

    def __len__(self) -> int:
        return len(self.actions)


@dataclass
class Demos:
    """A set of demonstrations for one environment (``env_id``)."""

    env_id: str
    obs_dim: int
    act_dim: int
    trajectories: List[Trajectory] = field(default_factory=list)
    control_hz: Optional[float] = None
    #: "person", "script", "policy" or "imported" (who made them), if known.
    source: Optional[str] = None
    #: The environment's own settings (for "drive": the road), if known.
    scenario: Optional[dict] = None

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """All state-action pairs stacked: (N, obs_dim), (N, act_dim) float64."""
        if not self.trajectories:
            return np.zeros((0, self.obs_dim)), np.zeros((0, self.act_dim))
        obs = np.concatenate([np.asarray(t.observations, dtype=np.float64) for t in self.trajectories])
        act = np.concatenate([np.asarray(t.actions, dtype=np.float64) for t in self.trajectories])
        return obs, act

    def num_pairs(self) -> int:
        return sum(len(t) for t in self.trajectories)

    def to_json(self) -> str:
        """The file's text, validated by the Rust reader."""
        return _red.validate_demos_json(json.dumps(_to_dict(self)))

    @staticmethod
    def from_json(text: str) -> "Demos":
        """Parses and validates file text (any readable format version)."""
        return _from_dict(json.loads(_red.validate_demos_json(text)))

    def write(self, path: "os.PathLike[str] | str") -> None:
        """Validates and writes the file (current format version)."""
        _red.write_demos_json(json.dumps(_to_dict(self)), os.fspath(path))

    def summary(self) -> str:
        """A few lines describing the set (``Demos::summary``)."""
        return _red.demos_summary(json.dumps(_to_dict(self)))


def read_demos(path: "os.PathLike[str] | str") -> Demos:
    """Reads and validates a demo file of the project's format."""
    return _from_dict(json.loads(_red.read_demos_json(os.fspath(path))))


def write_demos(demos: Demos, path: "os.PathLike[str] | str") -> None:
    """Validates and writes ``demos`` to ``path``."""
    demos.write(path)


def _rows(a: Any) -> list:
    return np.asarray(a, dtype=np.float64).tolist()


def _to_dict(d: Demos) -> dict:
    out: dict = {
        "format": _red.DEMO_FORMAT,
        "version": _red.DEMO_FORMAT_VERSION,
        "env_id": d.env_id,
        "obs_dim": int(d.obs_dim),
        "act_dim": int(d.act_dim),
        "trajectories": [],
    }
    if d.control_hz is not None:
        out["control_hz"] = float(d.control_hz)
    if d.source is not None:
        out["source"] = d.source
    if d.scenario is not None:
        out["scenario"] = d.scenario
    for t in d.trajectories:
        tj: dict = {
            "observations": _rows(t.observations),
            "actions": _rows(t.actions),
            "end": "terminated" if t.terminated else "truncated",
        }
        if t.rewards is not None:
            tj["rewards"] = np.asarray(t.rewards, dtype=np.float64).reshape(-1).tolist()
        out["trajectories"].append(tj)
    return out


def _from_dict(raw: dict) -> Demos:
    obs_dim, act_dim = raw["obs_dim"], raw["act_dim"]
    trajs = []
    for t in raw["trajectories"]:
        rewards = t.get("rewards")
        trajs.append(
            Trajectory(
                observations=np.asarray(t["observations"], dtype=np.float64).reshape(-1, obs_dim),
                actions=np.asarray(t["actions"], dtype=np.float64).reshape(-1, act_dim),
                rewards=None if rewards is None else np.asarray(rewards, dtype=np.float64),
                terminated=t["end"] == "terminated",
            )
        )
    return Demos(
        env_id=raw["env_id"],
        obs_dim=obs_dim,
        act_dim=act_dim,
        trajectories=trajs,
        control_hz=raw.get("control_hz"),
        source=raw.get("source"),
        scenario=raw.get("scenario"),
    )
