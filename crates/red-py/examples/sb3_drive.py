"""Trains a stable-baselines3 policy (SAC or PPO) on ``red/Drive-v0`` with
RED's reward fitted on a demonstration file, then evaluates the final policy
on the true reward (metres driven along the road).

    pip install ./crates/red-py stable-baselines3
    python crates/red-py/examples/sb3_drive.py [--algo sac|ppo] [--steps N] [--seed S]
        [--demo data/drive-scripted-expert.json] [--out runs/sb3-drive]

What it does, step by step (each step is the public API of the package):

1. ``red.read_demos`` reads the demo (the project's format); ``--demo`` may
   also be imitation's saved trajectories (``red.read_imitation``: a
   ``serialize.save`` folder or an ``.npz``) and ``--minari ID`` a Minari
   dataset (``red.from_minari``), both driven on the default road;
2. ``red.RedReward.fit("rnd", obs, act, seed=S)`` fits RND (the release's
   networks) and calibrates sigma1 on held-out expert scores, as the Rust
   driving experiment does; ``terminal_heuristic`` is its end-of-episode
   penalty;
3. ``red.RedRewardWrapper`` replaces the env's reward with RED's (the true
   one stays in ``info["true_reward"]``), on the demo's own road
   (``red.envs.make(demos.scenario)``, its 1200-step time limit);
4. SB3 trains on that reward only; the final policy is evaluated with
   ``--eval-runs`` deterministic episodes (reset seeds 1000, 1001, ..., as
   ``red-cli drive`` evaluates) on the true reward: distance driven, and its
   mean as a percentage of the road's length.

``--eval-roads N`` also evaluates on N roads the demo never saw, ``--load``
evaluates a saved ``model.zip`` without training. Not part of CI (torch is
several GB). Writes ``OUT/result.json`` and the policy ``OUT/model.zip``.
Measured results and wall times: docs/python.md.
"""

import argparse
import json
import os
import pathlib
import time

import numpy as np

import red

ROOT = pathlib.Path(__file__).resolve().parents[3]
EVAL_SEED = 1000  # red-experiments' drive::EVAL_SEED
UNSEEN_TRACK_SEED = 100  # red-experiments' drive::UNSEEN_FIRST_TRACK_SEED


def evaluate(model, config, runs):
    """Distances (sum of the env's true rewards) of `runs` deterministic
    episodes of the final policy on the road `config`."""
    env = red.envs.make(config)
    distances, ends = [], []
    for i in range(runs):
        obs, _ = env.reset(seed=EVAL_SEED + i)
        total, done = 0.0, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, r, terminated, truncated, info = env.step(action)
            total += r
            done = terminated or truncated
        distances.append(total)
        ends.append(
            "success" if info.get("success") == 1.0 else "collision" if info.get("collision") == 1.0 else "stopped"
        )
    env.close()
    return distances, ends


def behaviour_cloning(model, obs, act, epochs, seed):
    """Warm start (as ``red-cli drive`` does before SVG or SAC): fits the
    policy's deterministic action to the demo's actions by mean squared
    error, Adam 1e-3, batches of 64."""
    import torch

    policy = model.policy
    x = torch.as_tensor(obs, dtype=torch.float32)
    y = torch.as_tensor(np.clip(act, -0.999, 0.999), dtype=torch.float32)
    if hasattr(model, "actor"):  # SAC: the squashed Gaussian's mean
        params, forward = model.actor.parameters(), lambda b: model.actor(b, deterministic=True)
    else:  # PPO: the Gaussian's mean
        params, forward = policy.parameters(), lambda b: policy.get_distribution(b).distribution.mean
    opt = torch.optim.Adam(params, lr=1e-3)
    g = torch.Generator().manual_seed(seed)
    policy.set_training_mode(True)
    for _ in range(epochs):
        for idx in torch.randperm(len(x), generator=g).split(64):
            loss = torch.nn.functional.mse_loss(forward(x[idx]), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
    policy.set_training_mode(False)
    return loss.item()


def progress_callback(every):
    """Prints, every `every` steps, the time and the true distance of the
    training episodes since the last print (from info["true_reward"])."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Progress(BaseCallback):
        def _on_training_start(self):
            self.t0, self.ep, self.done = time.perf_counter(), 0.0, []

        def _on_step(self):
            for info, d in zip(self.locals["infos"], self.locals["dones"]):
                self.ep += info["true_reward"]
                if d:
                    self.done.append(self.ep)
                    self.ep = 0.0
            if self.num_timesteps % every == 0:
                seen = f"{np.mean(self.done):.1f} m over {len(self.done)}" if self.done else "none ended"
                print(f"  step {self.num_timesteps}: {time.perf_counter() - self.t0:.0f} s, "
                      f"training episodes' true distance {seen}", flush=True)
                self.done = []
            return True

    return Progress()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--algo", choices=["sac", "ppo"], default="sac")
    ap.add_argument("--steps", type=int, default=50_000, help="environment steps of training")
    ap.add_argument("--seed", type=int, default=0, help="seeds RED's fit, the env and SB3")
    ap.add_argument("--demo", default=str(ROOT / "data" / "drive-scripted-expert.json"),
                    help="the project's .json, or imitation's saved trajectories (a datasets folder or .npz)")
    ap.add_argument("--minari", default=None, help="a Minari dataset id instead of --demo")
    ap.add_argument("--eval-runs", type=int, default=5)
    ap.add_argument("--bc-epochs", type=int, default=0, help="behaviour cloning epochs on the demo before RL (0: none)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--progress-every", type=int, default=2500, help="print progress every N steps")
    ap.add_argument("--eval-roads", type=int, default=0,
                    help="also evaluate on N roads the demo never saw (track seeds 100, 101, ...; red-cli drive's)")
    ap.add_argument("--load", default=None, help="evaluate this saved model.zip instead of training one")
    ap.add_argument("--out", default=None, help="folder for result.json and model.zip")
    args = ap.parse_args()

    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.monitor import Monitor

    torch.set_num_threads(args.threads)
    t0 = time.perf_counter()

    if args.minari:
        demos = red.from_minari(args.minari, env_id="drive")
    elif args.demo.endswith(".json"):
        demos = red.read_demos(args.demo)
    else:
        demos = red.read_imitation(args.demo, env_id="drive")
    # imitation's and Minari's files do not record the road: the default one.
    road_config = demos.scenario or red.envs.default_config()
    obs, act = demos.pairs()
    reward = red.RedReward.fit("rnd", obs, act, seed=args.seed)
    terminal = reward.terminal_heuristic(obs, act)
    t_fit = time.perf_counter() - t0
    print(f"RED's reward: {reward!r}, fitted on {len(obs)} pairs in {t_fit:.1f} s")

    env = Monitor(red.RedRewardWrapper(red.envs.make(road_config), reward, terminal))
    env.reset(seed=args.seed)
    algo = SAC if args.algo == "sac" else PPO
    if args.load:
        model = algo.load(args.load, env=env, device="cpu")
    else:
        model = algo("MlpPolicy", env, seed=args.seed, verbose=0, device="cpu")

    after_bc = None
    if args.bc_epochs > 0 and not args.load:
        loss = behaviour_cloning(model, obs, act, args.bc_epochs, args.seed)
        d, e = evaluate(model, road_config, args.eval_runs)
        after_bc = {"distances_m": d, "ends": e, "mean_m": float(np.mean(d)), "bc_loss": loss}
        print(f"after {args.bc_epochs} epochs of behaviour cloning (MSE {loss:.4f}): "
              f"{np.mean(d):.1f} m, ends {e}")

    t1 = time.perf_counter()
    if not args.load:
        model.learn(total_timesteps=args.steps, callback=progress_callback(args.progress_every))
    t_train = time.perf_counter() - t1
    episodes = env.get_episode_rewards()
    if not args.load:
        print(f"trained {args.algo} for {args.steps} steps in {t_train:.0f} s "
              f"({args.steps / t_train:.0f} steps/s), {len(episodes)} episodes")

    distances, ends = evaluate(model, road_config, args.eval_runs)
    road = road_config["road_length"]
    mean = float(np.mean(distances))
    result = {
        "algo": args.algo,
        "steps": args.steps,
        "seed": args.seed,
        "demo": args.minari or (os.path.relpath(args.demo, ROOT) if args.demo.startswith(str(ROOT)) else args.demo),
        "sigma1": reward.sigma1,
        "bc_epochs": args.bc_epochs,
        "after_bc": after_bc,
        "eval_seeds": [EVAL_SEED + i for i in range(args.eval_runs)],
        "distances_m": distances,
        "ends": ends,
        "mean_m": mean,
        "std_m": float(np.std(distances)),
        "best_m": float(np.max(distances)),
        "percent_of_road": 100.0 * mean / road,
        "train_wall_s": None if args.load else t_train,
        "loaded": args.load,
        "total_wall_s": time.perf_counter() - t0,
        "versions": {"red": red.__version__, "torch": torch.__version__,
                     "stable_baselines3": __import__("stable_baselines3").__version__},
    }
    print(f"final policy, {args.eval_runs} deterministic runs: {mean:.1f} +- {result['std_m']:.1f} m "
          f"({result['percent_of_road']:.1f}% of the {road:.0f} m road), best {result['best_m']:.1f} m, ends {ends}")
    if args.eval_roads:
        # red-cli drive's: from 100 on, the demo's own road skipped.
        seeds = [t for t in range(UNSEEN_TRACK_SEED, UNSEEN_TRACK_SEED + args.eval_roads + 1)
                 if t != road_config["track_seed"]][: args.eval_roads]
        per_road = []
        for t in seeds:
            other = dict(road_config, track_seed=t)
            d, _ = evaluate(model, other, args.eval_runs)
            per_road.append(100.0 * float(np.mean(d)) / other["road_length"])
        result["unseen_roads"] = {
            "track_seeds": seeds,
            "percent_per_road": per_road,
            "percent_mean": float(np.mean(per_road)),
        }
        print(f"on {args.eval_roads} unseen roads: {np.mean(per_road):.1f}% of the road on average "
              f"(per road: {', '.join(f'{p:.0f}' for p in per_road)})")
    print(f"wall time {result['total_wall_s']:.0f} s")
    if args.out:
        out = pathlib.Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "result.json").write_text(json.dumps(result, indent=2) + "\n")
        model.save(out / "model.zip")


if __name__ == "__main__":
    main()
