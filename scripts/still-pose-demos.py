#!/usr/bin/env python3
"""Write synthetic variants of a demo file, for probing a support estimator.

usage: still-pose-demos.py DEMO OUT_DIR

For every expert pair of DEMO it writes, in OUT_DIR:
  still0.json   observation and action all zeros (a body at rest at the origin)
  zerovel.json  the observation's velocity half set to zero, the expert action
  zeroact.json  the expert observation with a zero action
  noise.json    the observation plus Gaussian noise of std 0.3, the expert action
"velocity half" assumes the Gymnasium layout qpos[1:] then qvel with one
more velocity than positions (Hopper 5 + 6, HalfCheetah and Walker2d 8 + 9). Score them with `red-cli support score --model M --demo F
--sigma1 S`, S the value calibrated on DEMO itself.
"""
import copy
import json
import random
import sys


def main() -> None:
    demo_path, out_dir = sys.argv[1], sys.argv[2]
    demo = json.load(open(demo_path))
    n_pos = demo["obs_dim"] // 2
    rng = random.Random(0)
    variants = {
        "still0": lambda o, a: ([0.0] * len(o), [0.0] * len(a)),
        "zerovel": lambda o, a: (o[:n_pos] + [0.0] * (len(o) - n_pos), a),
        "zeroact": lambda o, a: (o, [0.0] * len(a)),
        "noise": lambda o, a: ([x + rng.gauss(0.0, 0.3) for x in o], a),
    }
    for name, change in variants.items():
        out = copy.deepcopy(demo)
        for traj in out["trajectories"]:
            pairs = [change(o, a) for o, a in zip(traj["observations"], traj["actions"])]
            traj["observations"] = [p[0] for p in pairs]
            traj["actions"] = [p[1] for p in pairs]
        with open(f"{out_dir}/{name}.json", "w") as f:
            json.dump(out, f)


if __name__ == "__main__":
    main()
