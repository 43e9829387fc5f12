"""The driving env as a Gymnasium env: the checker, and step for step
against the Rust env (red_drive::make_env) and the shipped demonstration."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import red
from red import _red


def test_passes_gymnasiums_checker():
    env = gym.make("red/Drive-v0")
    check_env(env.unwrapped)
    assert env.spec.max_episode_steps == red.envs.default_config()["time_limit"]
    assert env.observation_space.shape == (24,) and env.action_space.shape == (2,)
    check_env(gym.make("red/Drive-v0", render_mode="rgb_array", render_width=300).unwrapped)


def _python_rollout(env, seed, policy, max_steps):
    obs, _ = env.reset(seed=seed)
    observations, actions, rewards = [obs], [], []
    term = trunc = False
    for _ in range(max_steps):
        a = policy(env, obs)
        obs, r, term, trunc, info = env.step(a)
        observations.append(obs)
        actions.append(np.asarray(a, dtype=np.float32))
        rewards.append(r)
        if term or trunc:
            break
    return np.array(observations), np.array(actions), np.array(rewards), term, trunc


@pytest.mark.parametrize("seed", [0, 7])
def test_matches_the_rust_env_step_for_step_random_actions(seed):
    rng = np.random.default_rng(seed)
    env = gym.make("red/Drive-v0")
    obs, acts, rews, term, trunc = _python_rollout(
        env, seed, lambda e, o: rng.uniform(-0.3, 1.0, size=2).astype(np.float32), 2000
    )
    r_obs, r_rews, r_term, r_trunc = _red.drive_rollout(acts.astype(np.float64), seed)
    np.testing.assert_array_equal(obs, r_obs)
    np.testing.assert_array_equal(rews, r_rews)
    assert (term, trunc) == (r_term, r_trunc)


def test_matches_the_rust_env_with_the_expert_to_the_end_and_at_the_time_limit():
    env = gym.make("red/Drive-v0")
    obs, acts, rews, term, trunc = _python_rollout(env, 3, lambda e, o: e.unwrapped.expert_action(), 5000)
    assert term and not trunc and rews.sum() > 900  # the expert drives the whole road
    r_obs, r_rews, r_term, r_trunc = _red.drive_rollout(acts.astype(np.float64), 3)
    np.testing.assert_array_equal(obs, r_obs)
    np.testing.assert_array_equal(rews, r_rews)
    assert (r_term, r_trunc) == (True, False)
    # A short time limit: Gymnasium's TimeLimit truncates where red-core's does.
    config = dict(red.envs.default_config(), time_limit=40)
    env = red.envs.make(config)
    obs, acts, rews, term, trunc = _python_rollout(env, 1, lambda e, o: np.array([0.0, 0.1], np.float32), 500)
    r = _red.drive_rollout(acts.astype(np.float64), 1, config_json=__import__("json").dumps(config))
    assert len(acts) == 40 and (term, trunc) == (False, True) == (r[2], r[3])
    np.testing.assert_array_equal(obs, r[0])


def test_replays_the_shipped_demonstration(demos):
    """The shipped demo was recorded by the Rust env on its road: its
    actions replayed from its first state give its observations and rewards
    (the file keeps 6 significant digits; measured: observations within
    7.9e-6, rewards within 3.0e-4, the largest at the last step)."""
    env = red.DriveEnv(config=demos.scenario)
    t = demos.trajectories[0]
    obs, _ = env.reset(options={"start_observation": t.observations[0]})
    np.testing.assert_allclose(obs, t.observations[0], atol=1e-5)
    for k, a in enumerate(t.actions):
        obs, r, term, trunc, _ = env.step(a)
        assert r == pytest.approx(t.rewards[k], abs=5e-4)
        if k + 1 < len(t):
            np.testing.assert_allclose(obs, t.observations[k + 1], atol=2e-5)
    assert term and t.terminated


def test_renders_an_rgb_array():
    env = red.DriveEnv(render_mode="rgb_array", render_width=400)
    env.reset(seed=0)
    for _ in range(20):
        env.step(env.expert_action())
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[1] == 400 and frame.shape[2] == 3
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3  # road, walls, obstacles, the path


def test_bad_actions_and_configs_are_refused():
    env = red.DriveEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="2 numbers"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="lane_widht"):
        red.DriveEnv(config={"lane_widht": 3.0})
