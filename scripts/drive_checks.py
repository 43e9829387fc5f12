#!/usr/bin/env python3
"""drive_checks.py RUNS_DIR NAME... [--seeds 0,1,2,3,4] [--curves | --runs]: the selection
checks (mean distance of 5 deterministic episodes on the selection's reset seeds, every
`select_every` steps) of the RED runs RUNS_DIR/NAME-DEMO-sK.
Default: per run, its training episodes, best and last check and the final policy's % of its
road; per NAME, how many runs end with a last check below 950 m, the mean of (best - last
check), and how many runs below 90% of their road had a 1000 m check and a lower last one.
--curves: every check as CSV. --runs: one CSV row per run (final and selected policy's % of
the demo's road and of unseen roads)."""
import glob, json, os, re, sys

args = sys.argv[1:]
seeds = None
if "--seeds" in args:
    i = args.index("--seeds")
    seeds = {int(s) for s in args[i + 1].split(",")}
    del args[i:i + 2]
mode = "curves" if "--curves" in args else "runs" if "--runs" in args else "summary"
root, names = args[0], [a for a in args[1:] if not a.startswith("--")]
ORDER = {"scripted": 0, "s11": 1, "s23": 2, "s37": 3}


def runs(name):
    found = []
    for d in glob.glob(os.path.join(root, name + "-*-s*")):
        m = re.match(re.escape(name) + r"-(.+)-s(\d+)$", os.path.basename(d))
        if not m or not os.path.exists(d + "/eval.json"):
            continue
        if seeds is not None and int(m.group(2)) not in seeds:
            continue
        found.append((ORDER.get(m.group(1), 9), int(m.group(2)), m.group(1), d))
    return [(demo, seed, d) for _, seed, demo, d in sorted(found)]


if mode == "curves":
    print("setting,demo,seed,step,check_distance_m")
if mode == "runs":
    print("setting,demo,seed,final_demo_road_pct,final_unseen_pct,selected_demo_road_pct,"
          "selected_unseen_pct")
for name in names:
    n = below = drift = low_last = 0
    gap = 0.0
    for demo, seed, d in runs(name):
        e = json.load(open(d + "/eval.json"))["methods"][0]
        f, s = e["final_policy"], e["selected_by_own_reward"]
        if mode == "runs":
            print(f"{name},{demo},{seed},{f['percent_of_road']:.1f},"
                  f"{f['unseen_roads']['percent_of_road']:.1f},{s['percent_of_road']:.1f},"
                  f"{s['unseen_roads']['percent_of_road']:.1f}")
            continue
        lines = open(d + "/metrics.csv").read().splitlines()
        ds = [(float(l.split(",")[3]), int(l.split(",")[2])) for l in lines if ",check," in l]
        if mode == "curves":
            for dist, step in ds:
                print(f"{name},{demo},{seed},{step},{dist:.1f}")
            continue
        eps = sum(1 for l in lines if ",train," in l)
        best, last = max(ds), ds[-1][0]
        n += 1
        gap += best[0] - last
        low_last += last < 950
        if f["percent_of_road"] < 90:
            below += 1
            drift += best[0] >= 999.9 and last < 999.9
        print(f"{os.path.basename(d)} episodes {eps} best check {best[0]:.0f} m at {best[1]} "
              f"last {last:.0f} final {f['percent_of_road']:.1f}")
    if mode == "summary":
        print(f"{name}: {n} runs, last check below 950 m in {low_last}, mean (best - last check) "
              f"{gap / max(n, 1):.0f} m; {below} runs below 90%, {drift} of them with a 1000 m "
              f"check and a lower last one")
