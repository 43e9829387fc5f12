"""The converters against the real ``imitation`` and ``minari`` packages.

Skipped where they are not installed (CI installs only numpy, gymnasium and
pytest; imitation pulls torch). Run by hand in an environment that has them:
imitation 1.0.1 pins Gymnasium 0.29 and stable-baselines3 2.2, minari 0.5
works with Gymnasium 0.29 and 1.x (docs/python.md says which versions were
run).
"""

import numpy as np
import pytest

import red


def _same(a, b, rtol=0.0):
    assert a.env_id == b.env_id and (a.obs_dim, a.act_dim) == (b.obs_dim, b.act_dim)
    assert len(a.trajectories) == len(b.trajectories)
    for x, y in zip(a.trajectories, b.trajectories):
        np.testing.assert_allclose(x.observations, y.observations, rtol=rtol, atol=0)
        np.testing.assert_allclose(x.actions, y.actions, rtol=rtol, atol=0)
        assert x.terminated == y.terminated
        if x.rewards is not None or y.rewards is not None:
            np.testing.assert_allclose(x.rewards, y.rewards, rtol=rtol, atol=0)


def test_imitation_hf_dataset_and_npz_round_trip(demos, tmp_path):
    serialize = pytest.importorskip("imitation.data.serialize")
    trajs = red.to_imitation_trajectories(demos)
    # imitation's own format (a HuggingFace datasets folder; it keeps
    # float64 arrays as float32, hence the tolerance) ...
    serialize.save(tmp_path / "hf", trajs)
    back = red.from_imitation_trajectories(serialize.load(tmp_path / "hf"), "drive")
    back.scenario, back.source = demos.scenario, demos.source
    _same(demos, back, rtol=1e-6)
    # ... and read by path without going through imitation's loader.
    by_path = red.read_imitation(tmp_path / "hf", "drive")
    by_path.scenario, by_path.source = demos.scenario, demos.source
    _same(demos, by_path, rtol=1e-6)
    # Its old .npz format, written by red, read by imitation.
    red.write_imitation_npz(demos, tmp_path / "d.npz")
    with pytest.warns(DeprecationWarning):
        loaded = serialize.load(tmp_path / "d.npz")
    assert len(loaded) == len(demos.trajectories)
    np.testing.assert_array_equal(loaded[0].acts, demos.trajectories[0].actions)


def test_imitation_rollouts_convert(tmp_path):
    pytest.importorskip("imitation")
    from imitation.data import rollout
    from imitation.data.wrappers import RolloutInfoWrapper
    from stable_baselines3.common.vec_env import DummyVecEnv

    config = dict(red.envs.default_config(), road_length=200.0, time_limit=300)
    venv = DummyVecEnv([lambda: RolloutInfoWrapper(red.envs.make(config))])
    rng = np.random.default_rng(0)
    # imitation's rollout of a random policy (policy=None): TrajectoryWithRew
    # with infos, obs one longer than acts.
    trajs = rollout.rollout(None, venv, rollout.make_min_episodes(2), rng=rng, exclude_infos=False)
    demos = red.from_imitation_trajectories(trajs, "drive")
    assert len(demos.trajectories) == len(trajs)
    for t, d in zip(trajs, demos.trajectories):
        np.testing.assert_array_equal(d.observations, t.obs[:-1])
        np.testing.assert_allclose(d.actions, t.acts)
        np.testing.assert_allclose(d.rewards, t.rews)
    # The converted demos fit a reward.
    obs, act = demos.pairs()
    reward = red.RedReward.fit("rnd", obs, act, seed=0, epochs=2)
    assert reward.reward(obs[:3], act[:3]).shape == (3,)


def test_minari_dataset_converts(tmp_path, monkeypatch):
    minari = pytest.importorskip("minari")
    from minari.data_collector import EpisodeBuffer

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    config = dict(red.envs.default_config(), road_length=200.0, time_limit=300)
    env = red.envs.make(config)
    expert, buffers = [], []
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        acts, observations, rews, terms, truncs, done = [], [obs], [], [], [], False
        while not done:
            a = env.unwrapped.expert_action()
            obs, r, terminated, truncated, _ = env.step(a)
            acts.append(a)
            observations.append(obs)
            rews.append(r)
            terms.append(terminated)
            truncs.append(truncated)
            done = terminated or truncated
        expert.append((np.array(observations), np.array(acts), np.array(rews), terminated))
        buffers.append(
            EpisodeBuffer(
                id=seed, seed=seed, observations=np.array(observations), actions=np.array(acts),
                rewards=rews, terminations=terms, truncations=truncs,
            )
        )
    # Written the way Minari's own datasets are (Arrow storage: pyarrow comes
    # with minari's dependencies, h5py does not; DataCollector would need jax).
    minari.create_dataset_from_buffers(
        "red/drive-expert-v0", buffers, env=env, algorithm_name="scripted expert", data_format="arrow"
    )

    demos = red.from_minari("red/drive-expert-v0", env_id="drive", control_hz=20.0)
    assert len(demos.trajectories) == 2
    for (o, a, r, term), t in zip(expert, demos.trajectories):
        np.testing.assert_allclose(t.observations, o[:-1])
        np.testing.assert_allclose(t.actions, a, rtol=1e-6)
        np.testing.assert_allclose(t.rewards, r)
        assert t.terminated == term
    # The dataset object works as well as its id.
    again = red.from_minari(minari.load_dataset("red/drive-expert-v0"), env_id="drive", control_hz=20.0)
    _same(demos, again)
