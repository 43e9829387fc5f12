"""Converters from the formats imitation-learning users have to the
project's demo format (:class:`red.demos.Demos`), and back to imitation's.

* imitation's ``Trajectory`` / ``TrajectoryWithRew`` lists (any objects with
  ``obs`` (T+1, obs_dim), ``acts`` (T, act_dim), ``terminal`` and optionally
  ``rews`` (T,); imitation itself is not needed);
* imitation's saved trajectories: its HuggingFace ``datasets`` folders
  (imitation >= 1.0's ``serialize.save``; :func:`read_imitation`) and its
  ``.npz`` files (``imitation.data.serialize``'s old format:
  ``obs``, ``acts``, ``infos`` (object array), ``terminal``, ``indices``,
  optional ``rews``; an ``acs`` key is read as ``acts``);
* Minari datasets (``minari`` must be installed for ids; a dataset object or
  any iterable of episodes with ``observations`` (T+1, ...), ``actions``,
  ``rewards``, ``terminations`` works without it).

imitation's and Minari's observation arrays hold one more observation than
actions (the state after the last action); the project's format pairs each
action with the state it was taken in, so that last observation is dropped
on import. Exporting back to imitation needs it: ``final_obs`` gives it, or
the last recorded observation is repeated (said in the docstring, never
silently guessed elsewhere).
"""

from __future__ import annotations

import os
from typing import Any, Iterable, List, Optional, Sequence

import numpy as np

from .demos import Demos, Trajectory


def _flat(a: Any, what: str, i: int) -> np.ndarray:
    arr = np.asarray(a)
    if arr.dtype == object:
        raise ValueError(
            f"trajectory {i}: {what} is an object array; only flat numeric "
            "(Box) observations and actions can be converted"
        )
    arr = arr.astype(np.float64)
    if arr.ndim == 1:
        arr = arr[:, None]
    return arr.reshape(arr.shape[0], -1)


def _trajectory(i: int, obs: Any, acts: Any, rews: Any, terminated: bool) -> Trajectory:
    o = _flat(obs, "obs", i)
    a = _flat(acts, "acts", i)
    if len(o) == len(a) + 1:
        o = o[:-1]
    elif len(o) != len(a):
        raise ValueError(
            f"trajectory {i}: {len(o)} observations for {len(a)} actions; expected "
            f"{len(a) + 1} (imitation/Minari: one more than actions) or {len(a)}"
        )
    r = None if rews is None else np.asarray(rews, dtype=np.float64).reshape(-1)
    if r is not None and len(r) != len(a):
        raise ValueError(f"trajectory {i}: {len(r)} rewards for {len(a)} actions")
    return Trajectory(observations=o, actions=a, rewards=r, terminated=bool(terminated))


def _demos(env_id: str, trajs: List[Trajectory], control_hz: Optional[float]) -> Demos:
    if not trajs:
        raise ValueError("no trajectories to convert")
    d = Demos(
        env_id=env_id,
        obs_dim=trajs[0].observations.shape[1],
        act_dim=trajs[0].actions.shape[1],
        trajectories=trajs,
        control_hz=control_hz,
        source="imported",
    )
    # Validates through the Rust reader (dimensions, finite numbers, ...).
    Demos.from_json(d.to_json())
    return d


def from_imitation_trajectories(
    trajectories: Sequence[Any], env_id: str, control_hz: Optional[float] = None
) -> Demos:
    """imitation ``Trajectory`` / ``TrajectoryWithRew`` objects to Demos."""
    trajs = [
        _trajectory(i, t.obs, t.acts, getattr(t, "rews", None), getattr(t, "terminal", True))
        for i, t in enumerate(trajectories)
    ]
    return _demos(env_id, trajs, control_hz)


def read_imitation_npz(path: "os.PathLike[str] | str", env_id: str, control_hz: Optional[float] = None) -> Demos:
    """An imitation ``.npz`` trajectory file to Demos (``infos`` are dropped)."""
    data = np.load(os.fspath(path), allow_pickle=True)
    keys = set(data.files)
    acts_key = "acts" if "acts" in keys else "acs" if "acs" in keys else None
    missing = [k for k in ("obs", "indices", "terminal") if k not in keys]
    if acts_key is None or missing:
        raise ValueError(
            f"{os.fspath(path)}: not an imitation trajectory file: needs the keys obs, acts "
            f"(or acs), indices and terminal; it has {sorted(keys)}"
        )
    indices = np.asarray(data["indices"], dtype=np.int64)
    k = len(indices)
    obs = np.split(data["obs"], indices + np.arange(k) + 1)
    acts = np.split(data[acts_key], indices)
    rews = np.split(data["rews"], indices) if "rews" in keys else [None] * (k + 1)
    terminal = np.asarray(data["terminal"]).reshape(-1)
    if len(terminal) != k + 1:
        raise ValueError(
            f"{os.fspath(path)}: {len(terminal)} terminal flags for {k + 1} trajectories "
            f"(indices has {k} split points)"
        )
    trajs = [_trajectory(i, obs[i], acts[i], rews[i], terminal[i]) for i in range(k + 1)]
    return _demos(env_id, trajs, control_hz)


def read_imitation(path: "os.PathLike[str] | str", env_id: str, control_hz: Optional[float] = None) -> Demos:
    """Trajectories saved by imitation to Demos: a folder written by
    ``imitation.data.serialize.save`` (imitation >= 1.0: a HuggingFace
    ``datasets`` folder with columns ``obs``, ``acts``, ``infos``,
    ``terminal`` and optionally ``rews``; needs the ``datasets`` package,
    which imitation installs, but not imitation itself) or an ``.npz`` file
    (:func:`read_imitation_npz`)."""
    p = os.fspath(path)
    if not os.path.isdir(p):
        return read_imitation_npz(p, env_id, control_hz)
    try:
        import datasets
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise ImportError(
            f"{p} is a folder (imitation's HuggingFace datasets format): reading it needs "
            "the datasets package (pip install datasets)"
        ) from e
    ds = datasets.load_from_disk(p)
    missing = [k for k in ("obs", "acts", "terminal") if k not in ds.column_names]
    if missing:
        raise ValueError(
            f"{p}: not imitation's trajectory dataset: missing the columns {missing} "
            f"(it has {ds.column_names})"
        )
    cols = ["obs", "acts", "terminal"] + (["rews"] if "rews" in ds.column_names else [])
    rows = ds.select_columns(cols).with_format("numpy")
    trajs = [
        _trajectory(i, row["obs"], row["acts"], row.get("rews"), bool(row["terminal"]))
        for i, row in enumerate(rows)
    ]
    return _demos(env_id, trajs, control_hz)


def _final_obs(demos: Demos, final_obs: Optional[Sequence[Any]]) -> List[np.ndarray]:
    if final_obs is None:
        return [t.observations[-1] for t in demos.trajectories]
    if len(final_obs) != len(demos.trajectories):
        raise ValueError(
            f"final_obs has {len(final_obs)} entries for {len(demos.trajectories)} trajectories"
        )
    return [np.asarray(o, dtype=np.float64).reshape(demos.obs_dim) for o in final_obs]


def write_imitation_npz(
    demos: Demos, path: "os.PathLike[str] | str", final_obs: Optional[Sequence[Any]] = None
) -> None:
    """Demos to imitation's ``.npz`` format. Each trajectory's observations
    get the state after its last action appended: ``final_obs[i]`` if
    given, else a repeat of its last recorded observation (the project's
    format does not keep that state). ``infos`` are written as ``None``s;
    ``rews`` only when every trajectory has rewards."""
    last = _final_obs(demos, final_obs)
    trajs = demos.trajectories
    out = {
        "obs": np.concatenate([np.vstack([t.observations, o[None, :]]) for t, o in zip(trajs, last)]),
        "acts": np.concatenate([t.actions for t in trajs]),
        "infos": np.array([None] * demos.num_pairs(), dtype=object),
        "terminal": np.array([t.terminated for t in trajs]),
        "indices": np.cumsum([len(t) for t in trajs[:-1]]).astype(np.int64),
    }
    if all(t.rewards is not None for t in trajs):
        out["rews"] = np.concatenate([t.rewards for t in trajs])
    np.savez_compressed(os.fspath(path), **out)


def to_imitation_trajectories(demos: Demos, final_obs: Optional[Sequence[Any]] = None) -> list:
    """Demos to imitation ``TrajectoryWithRew`` (or ``Trajectory``) objects;
    needs ``imitation``. ``final_obs`` as in :func:`write_imitation_npz`."""
    from imitation.data.types import Trajectory as ITrajectory
    from imitation.data.types import TrajectoryWithRew

    out = []
    for t, o in zip(demos.trajectories, _final_obs(demos, final_obs)):
        obs = np.vstack([t.observations, o[None, :]])
        infos = None
        if t.rewards is not None:
            out.append(TrajectoryWithRew(obs=obs, acts=t.actions, infos=infos, terminal=t.terminated, rews=t.rewards))
        else:
            out.append(ITrajectory(obs=obs, acts=t.actions, infos=infos, terminal=t.terminated))
    return out


def from_minari(
    dataset: Any, env_id: Optional[str] = None, control_hz: Optional[float] = None
) -> Demos:
    """A Minari dataset to Demos.

    ``dataset`` is a dataset id (loaded with ``minari.load_dataset``, which
    needs ``minari`` and the dataset downloaded), a ``MinariDataset``, or any
    iterable of episodes with ``observations``, ``actions``, ``rewards``,
    ``terminations`` (and ``truncations``). An episode counts as terminated
    when its last ``terminations`` flag is set. ``env_id`` defaults to the
    dataset's environment id."""
    if isinstance(dataset, str):
        try:
            import minari
        except ImportError as e:  # pragma: no cover - depends on the machine
            raise ImportError(
                "reading a Minari dataset by id needs minari: pip install minari"
            ) from e
        dataset = minari.load_dataset(dataset)
    if env_id is None:
        spec = getattr(dataset, "spec", None)
        env_spec = getattr(spec, "env_spec", None)
        env_id = getattr(env_spec, "id", None) or getattr(spec, "dataset_id", None) or "minari"
    episodes: Iterable[Any] = (
        dataset.iterate_episodes() if hasattr(dataset, "iterate_episodes") else dataset
    )
    trajs = []
    for i, ep in enumerate(episodes):
        term = np.asarray(ep.terminations).reshape(-1)
        trajs.append(
            _trajectory(i, ep.observations, ep.actions, ep.rewards, bool(term[-1]) if len(term) else False)
        )
    return _demos(env_id, trajs, control_hz)
