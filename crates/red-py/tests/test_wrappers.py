"""The reward-replacing wrappers on single and vector envs."""

import gymnasium as gym
import numpy as np
import pytest

import red


@pytest.fixture(scope="module")
def reward(demos):
    obs, act = demos.pairs()
    return red.RedReward.fit("rnd", obs, act, seed=0, epochs=20), obs, act


def test_single_env_reward_is_reds_and_true_reward_is_kept(reward):
    r, obs_e, act_e = reward
    h = r.terminal_heuristic(obs_e, act_e)
    env = red.RedRewardWrapper(gym.make("red/Drive-v0"), r, terminal=h)
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(2000):
        a = rng.uniform(-1, 1, size=2).astype(np.float32)
        nxt, rew, term, trunc, info = env.step(a)
        expect = r.reward(obs[None, :], a[None, :].astype(np.float64))[0]
        if term or trunc:
            expect += h.penalty(expect)
        assert rew == pytest.approx(expect, rel=1e-12)
        assert info["true_reward"] > -1 and "distance" in info
        obs = nxt
        if term or trunc:
            break
    assert term or trunc


# Gymnasium 0.29 (imitation's pin) has no VectorWrapper nor AutoresetMode.
OLD_GYM = not hasattr(gym.vector, "AutoresetMode")


@pytest.mark.skipif(OLD_GYM, reason="vector wrapper needs gymnasium >= 1.0")
@pytest.mark.parametrize(
    "mode", [] if OLD_GYM else [gym.vector.AutoresetMode.NEXT_STEP, gym.vector.AutoresetMode.SAME_STEP]
)
def test_vector_env(reward, mode):
    r, _, _ = reward
    n = 3
    venv = gym.vector.SyncVectorEnv(
        [lambda: gym.make("red/Drive-v0") for _ in range(n)], autoreset_mode=mode
    )
    plain = gym.vector.SyncVectorEnv(
        [lambda: gym.make("red/Drive-v0") for _ in range(n)], autoreset_mode=mode
    )
    env = red.RedRewardVectorWrapper(venv, r)
    obs, _ = env.reset(seed=[0, 1, 2])
    plain.reset(seed=[0, 1, 2])
    rng = np.random.default_rng(1)
    resetting = np.zeros(n, dtype=bool)
    ends = 0
    for _ in range(400):
        a = rng.uniform(-1, 1, size=(n, 2)).astype(np.float32)
        nxt, rew, term, trunc, info = env.step(a)
        _, true_r, _, _, _ = plain.step(a)
        np.testing.assert_array_equal(info["true_reward"], true_r)
        expect = r.reward(obs, a.astype(np.float64))
        if mode == gym.vector.AutoresetMode.NEXT_STEP:
            expect = np.where(resetting, true_r, expect)
            resetting = term | trunc
        np.testing.assert_allclose(rew, expect, rtol=1e-12)
        ends += int((term | trunc).sum())
        obs = nxt
    assert ends > 0  # random driving crashes: the autoreset path was taken


@pytest.mark.skipif(not OLD_GYM, reason="Gymnasium < 1.0 only")
def test_vector_wrapper_says_it_needs_gymnasium_1(reward):
    r, _, _ = reward
    with pytest.raises(ImportError, match="gymnasium >= 1.0"):
        red.RedRewardVectorWrapper(None, r)
