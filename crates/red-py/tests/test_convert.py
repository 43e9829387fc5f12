"""Demo files and the converters round-trip."""

import json
from dataclasses import dataclass
from typing import Optional

import numpy as np
import pytest

import red


def _same(a, b):
    assert (a.env_id, a.obs_dim, a.act_dim) == (b.env_id, b.obs_dim, b.act_dim)
    assert len(a.trajectories) == len(b.trajectories)
    for s, t in zip(a.trajectories, b.trajectories):
        np.testing.assert_array_equal(s.observations, t.observations)
        np.testing.assert_array_equal(s.actions, t.actions)
        assert s.terminated == t.terminated
        if s.rewards is None:
            assert t.rewards is None
        else:
            np.testing.assert_array_equal(s.rewards, t.rewards)


def test_demo_file_round_trip(demos, demo_path, tmp_path):
    assert demos.env_id == "drive" and demos.num_pairs() == 721 and demos.source == "script"
    assert demos.scenario["track_seed"] == 0
    demos.write(tmp_path / "d.json")
    again = red.read_demos(tmp_path / "d.json")
    _same(demos, again)
    assert again.scenario == demos.scenario and again.control_hz == 20.0
    assert json.loads(open(tmp_path / "d.json").read())["format"] == "red-demos"
    assert "721" in demos.summary()


def test_invalid_demos_are_refused_with_the_place(demos, tmp_path):
    t = demos.trajectories[0]
    bad_obs = t.observations.copy()
    bad_obs[5, 3] = np.nan
    bad = red.Demos("drive", 24, 2, [red.Trajectory(bad_obs, t.actions)])
    with pytest.raises(ValueError, match="step 5"):
        bad.write(tmp_path / "bad.json")


@dataclass
class FakeTrajectory:
    """imitation's TrajectoryWithRew, field for field (imitation itself is
    not needed)."""

    obs: np.ndarray
    acts: np.ndarray
    infos: Optional[np.ndarray]
    terminal: bool
    rews: np.ndarray


def _fake(rng, lengths, obs_dim=5, act_dim=2):
    return [
        FakeTrajectory(
            obs=rng.normal(size=(n + 1, obs_dim)).astype(np.float32),
            acts=rng.uniform(-1, 1, size=(n, act_dim)),
            infos=np.array([{"k": i} for i in range(n)], dtype=object),
            terminal=bool(i % 2),
            rews=rng.normal(size=n),
        )
        for i, n in enumerate(lengths)
    ]


def test_imitation_trajectories_and_npz_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    trajs = _fake(rng, [7, 3, 11])
    demos = red.from_imitation_trajectories(trajs, env_id="Toy-v0", control_hz=10.0)
    assert (demos.obs_dim, demos.act_dim, demos.num_pairs(), demos.source) == (5, 2, 21, "imported")
    for t, d in zip(trajs, demos.trajectories):
        np.testing.assert_array_equal(d.observations, t.obs[:-1].astype(np.float64))
        assert d.terminated == t.terminal
    # Demos -> imitation npz (with the true final observations) -> Demos.
    path = tmp_path / "traj.npz"
    red.write_imitation_npz(demos, path, final_obs=[t.obs[-1] for t in trajs])
    data = np.load(path, allow_pickle=True)
    np.testing.assert_array_equal(data["obs"], np.concatenate([t.obs for t in trajs]).astype(np.float64))
    assert list(data["indices"]) == [7, 10] and data["infos"].dtype == object
    again = red.read_imitation_npz(path, env_id="Toy-v0", control_hz=10.0)
    _same(demos, again)
    # And through the project's file.
    demos.write(tmp_path / "d.json")
    _same(demos, red.read_demos(tmp_path / "d.json"))


def test_imitation_npz_written_the_way_imitation_writes_it(tmp_path):
    """A file laid out as imitation's `serialize.save` wrote npz files
    (obs with one extra row per trajectory, `infos` object arrays, `acs`
    accepted for `acts`)."""
    rng = np.random.default_rng(1)
    trajs = _fake(rng, [4, 6])
    path = tmp_path / "old.npz"
    np.savez_compressed(
        path,
        obs=np.concatenate([t.obs for t in trajs]),
        acs=np.concatenate([t.acts for t in trajs]),
        infos=np.concatenate([t.infos for t in trajs]),
        terminal=np.array([t.terminal for t in trajs]),
        rews=np.concatenate([t.rews for t in trajs]),
        indices=np.array([4]),
    )
    demos = red.read_imitation_npz(path, env_id="Toy-v0")
    assert [len(t) for t in demos.trajectories] == [4, 6]
    np.testing.assert_array_equal(demos.trajectories[1].rewards, trajs[1].rews)
    with pytest.raises(ValueError, match="needs the keys"):
        np.savez(tmp_path / "x.npz", obs=np.zeros((2, 2)))
        red.read_imitation_npz(tmp_path / "x.npz", env_id="x")


@dataclass
class FakeEpisode:
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray


def test_minari_episodes():
    rng = np.random.default_rng(2)
    eps = []
    for n, ended in [(5, True), (8, False)]:
        term = np.zeros(n, dtype=bool)
        term[-1] = ended
        eps.append(
            FakeEpisode(
                rng.normal(size=(n + 1, 3)), rng.normal(size=(n, 1)), rng.normal(size=n), term, ~term & (np.arange(n) == n - 1)
            )
        )
    demos = red.from_minari(eps, env_id="Pendulum-v1")
    assert [t.terminated for t in demos.trajectories] == [True, False]
    assert (demos.obs_dim, demos.act_dim) == (3, 1)
    np.testing.assert_array_equal(demos.trajectories[1].observations, eps[1].observations[:-1])


def test_converter_errors_say_what_is_wrong():
    rng = np.random.default_rng(3)
    t = _fake(rng, [4])[0]
    t.obs = t.obs[:2]
    with pytest.raises(ValueError, match="2 observations for 4 actions"):
        red.from_imitation_trajectories([t], env_id="x")
