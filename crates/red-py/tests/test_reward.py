"""RED's reward from Python against the Rust CLI and the Rust defaults."""

import re
import threading
import time

import numpy as np
import pytest

import red
from conftest import run_cli


@pytest.fixture(scope="module")
def cli_rnd(tmp_path_factory, demo_path):
    """A model fitted by `red-cli support fit` (RND, seed 3) and the CLI's
    `support score` output on the shipped demo."""
    path = tmp_path_factory.mktemp("cli") / "rnd.json"
    run_cli("support", "fit", "--demo", str(demo_path), "--estimator", "rnd", "--seed", "3", "--out", str(path))
    scored = run_cli("support", "score", "--model", str(path), "--demo", str(demo_path))
    return path, scored


def test_cli_model_loads_and_scores_like_the_cli(cli_rnd, demos):
    path, scored = cli_rnd
    model = red.SupportModel.load(path)
    assert (model.kind, model.obs_dim, model.act_dim) == ("rnd", 24, 2)
    obs, act = demos.pairs()
    scores = model.score(obs, act)
    assert scores.shape == (demos.num_pairs(),) and scores.dtype == np.float64
    # The CLI prints the mean score with 5 significant digits and sigma1
    # (calibrated on the scored pairs, RedRewardConfig's default) with 7.
    mean = float(re.search(r"score L\s+mean (\S+)", scored).group(1))
    sigma1 = float(re.search(r"sigma1 = (\S+)", scored).group(1))
    assert scores.mean() == pytest.approx(mean, rel=1e-4)
    reward = red.RedReward(model, obs, act)
    assert reward.sigma1 == pytest.approx(sigma1, rel=1e-6)
    share = float(re.search(r"reward >= 0.9: (\S+)", scored).group(1))
    assert np.mean(reward.reward(obs, act) >= 0.9) == pytest.approx(share, abs=1e-3)


def test_python_fit_is_the_cli_fit(cli_rnd, demos, tmp_path):
    """Same seed, same code: the model fitted from Python scores like the
    CLI's to 1e-6 (in fact bit for bit), and survives save/load."""
    path, _ = cli_rnd
    obs, act = demos.pairs()
    cli = red.SupportModel.load(path).score(obs, act)
    mine = red.SupportModel.fit("rnd", obs, act, seed=3)
    np.testing.assert_allclose(mine.score(obs, act), cli, rtol=1e-6, atol=0)
    mine.save(tmp_path / "m.json")
    again = red.SupportModel.load(tmp_path / "m.json")
    np.testing.assert_array_equal(again.score(obs, act), mine.score(obs, act))


def test_dtypes_and_memory_orders_give_the_same_numbers(demos):
    obs, act = demos.pairs()
    obs, act = obs[:64], act[:64]
    model = red.SupportModel.fit("rnd", obs, act, seed=0, epochs=5)
    base = model.score(obs, act)
    np.testing.assert_array_equal(model.score(np.asfortranarray(obs), np.asfortranarray(act)), base)
    wide = np.repeat(obs, 2, axis=1)[:, ::2]  # a strided view
    np.testing.assert_array_equal(model.score(wide, act), base)
    o32, a32 = obs.astype(np.float32), act.astype(np.float32)
    np.testing.assert_array_equal(
        model.score(o32, a32), model.score(o32.astype(np.float64), a32.astype(np.float64))
    )
    np.testing.assert_array_equal(model.score(obs.tolist(), act.tolist()), base)


def test_shape_errors_say_what_was_expected(demos):
    obs, act = demos.pairs()
    r = red.RedReward.fit("rnd", obs[:50], act[:50], seed=0, epochs=2, folds=None)
    with pytest.raises(ValueError, match=r"obs must be a 2-D array of shape \(n, 24\).*got shape \(50, 23\)"):
        r.reward(obs[:50, :23], act[:50])
    with pytest.raises(ValueError, match=r"act must be a 2-D array of shape \(n, 2\).*got shape \(2,\).*act\[None, :\]"):
        r.reward(obs[:1], act[0])
    with pytest.raises(ValueError, match="same number of rows"):
        r.reward(obs[:5], act[:4])
    with pytest.raises(ValueError, match='unknown estimator `svm`: use "rnd", "ae" or "kpca"'):
        red.SupportModel.fit("svm", obs, act)
    with pytest.raises(ValueError, match="unknown field `epochz`"):
        red.SupportModel.fit("rnd", obs[:20], act[:20], config={"epochz": 3})


@pytest.mark.parametrize("kind,extra", [("rnd", {"epochs": 20}), ("ae", {"epochs": 20}), ("kpca", {})])
def test_each_estimator_rewards_expert_pairs_above_random_pairs(demos, kind, extra):
    obs, act = demos.pairs()
    idx = np.arange(0, len(obs), 4)  # 181 pairs keep kernel PCA quick
    s, a = obs[idx], act[idx]
    r = red.RedReward.fit(kind, s, a, seed=1, **extra)
    assert r.model.kind == kind and r.sigma1 > 0
    on = r.reward(s, a)
    rng = np.random.default_rng(0)
    off = r.reward(s, rng.uniform(-1, 1, size=a.shape))
    assert np.all((on > 0) & (on <= 1)) and np.all((off >= 0) & (off <= 1))
    assert on.mean() > off.mean()


def test_fit_is_reproducible_from_the_seed(demos):
    obs, act = demos.pairs()
    a = red.RedReward.fit("rnd", obs[:100], act[:100], seed=5, epochs=10)
    b = red.RedReward.fit("rnd", obs[:100], act[:100], seed=5, epochs=10)
    c = red.RedReward.fit("rnd", obs[:100], act[:100], seed=6, epochs=10)
    assert a.sigma1 == b.sigma1
    np.testing.assert_array_equal(a.reward(obs, act), b.reward(obs, act))
    assert not np.array_equal(a.score(obs, act), c.score(obs, act))


def test_sigma1_rules(demos):
    obs, act = demos.pairs()
    s, a = obs[:120], act[:120]
    model = red.SupportModel.fit("rnd", s, a, seed=0, epochs=10)
    assert red.default_sigma1_rule() == (0.9, 0.9)
    calibrated = red.RedReward(model, s, a)
    # The 0.9 quantile of the calibration scores gets reward 0.9.
    assert np.quantile(calibrated.reward(s, a), 0.1) == pytest.approx(0.9, rel=1e-9)
    fixed = red.RedReward(model, sigma1=2.5)
    np.testing.assert_allclose(fixed.reward(s, a), np.exp(-2.5 * model.score(s, a)), rtol=1e-12)
    with pytest.raises(ValueError, match="sigma1"):
        red.RedReward(model, sigma1=-1.0)
    with pytest.raises(ValueError, match="expert pairs"):
        red.RedReward(model)
    # Held-out calibration (the driving experiment's rule) gives a smaller
    # sigma1 than calibrating on the training pairs.
    held = red.RedReward.fit("rnd", s, a, seed=0, epochs=10, folds=5)
    train = red.RedReward.fit("rnd", s, a, seed=0, epochs=10, folds=None)
    assert held.sigma1 < train.sigma1
    r, g = held.reward_grad_action(s, a)
    assert r.shape == (120,) and g.shape == (120, 2)


def test_terminal_heuristic(demos):
    obs, act = demos.pairs()
    r = red.RedReward.fit("rnd", obs[:100], act[:100], seed=0, epochs=5)
    h = r.terminal_heuristic(obs[:100], act[:100])
    mean = r.reward(obs[:100], act[:100]).mean()
    assert h.expert_mean_reward == pytest.approx(mean, rel=1e-12)
    # Defaults sigma2 = 10, sigma3 = 0.5 (TerminalHeuristicConfig::default()).
    assert h.penalty(0.49 * mean) == pytest.approx(-10 * mean)
    assert h.penalty(0.51 * mean) == 0.0
    h2 = red.TerminalHeuristic(0.8, sigma2=2.0, sigma3=0.25)
    assert (h2.penalty(0.1), h2.penalty(0.3)) == (pytest.approx(-1.6), 0.0)
    with pytest.raises(ValueError, match="sigma2"):
        red.TerminalHeuristic(0.8, sigma2=float("nan"))


def test_calls_release_the_gil(demos):
    """Another Python thread runs while a fit runs in Rust."""
    obs, act = demos.pairs()
    done = threading.Event()
    ticks = []

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    time.sleep(0.01)
    n0 = len(ticks)
    start = time.perf_counter()
    red.SupportModel.fit("rnd", obs, act, seed=0, epochs=30)
    elapsed = time.perf_counter() - start
    n1 = len(ticks)
    done.set()
    t.join()
    assert elapsed > 0.05, "the fit was too short to tell"
    # With the GIL held the counter would not move during the fit.
    assert n1 - n0 >= 5


@pytest.mark.parametrize("method", ["reward", "score", "reward_grad_action"])
def test_reward_calls_release_the_gil(demos, method):
    """Another Python thread runs during one `reward` / `score` /
    `reward_grad_action` call on a large batch (not only between calls:
    only ticks stamped strictly inside the call are counted)."""
    obs, act = demos.pairs()
    reward = red.RedReward.fit("rnd", obs, act, seed=0, epochs=2, folds=None)
    call = getattr(reward, method)
    # Grow the batch until one call takes long enough to tell (>= 0.2 s).
    reps, elapsed = 8, 0.0
    while True:
        s, a = np.tile(obs, (reps, 1)), np.tile(act, (reps, 1))
        start = time.perf_counter()
        call(s, a)
        elapsed = time.perf_counter() - start
        if elapsed >= 0.2 or reps >= 4096:
            break
        reps *= 2
    assert elapsed >= 0.2, "the call was too short to tell"
    done = threading.Event()
    ticks = []

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    time.sleep(0.02)
    start = time.perf_counter()
    call(s, a)
    end = time.perf_counter()
    done.set()
    t.join()
    inside = [x for x in ticks if start < x < end]
    # Holding the GIL, the counter could stamp at most one tick (before the
    # call took the GIL); releasing it, about one per millisecond.
    assert len(inside) >= 10, f"{len(inside)} ticks during a {end - start:.3f} s call"
