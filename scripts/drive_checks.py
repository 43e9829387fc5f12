#!/usr/bin/env python3
"""drive_checks.py RUNS_DIR NAME...: per run NAME-DEMO-sK, the best check (mean distance of the
selection's 5 deterministic episodes) and its step, the last check, the final policy's % of
its road; and how many runs below 90% had a 1000 m check. --curves: every check as CSV."""
import glob, json, os, re, sys
root, names = sys.argv[1], [a for a in sys.argv[2:] if not a.startswith("--")]
curves = "--curves" in sys.argv
if curves:
    print("setting,demo,seed,step,check_distance_m")
for name in names:
    below = drift = 0
    for d in sorted(glob.glob(os.path.join(root, name + "-*-s*"))):
        m = re.match(re.escape(name) + r"-(.+)-s(\d+)$", os.path.basename(d))
        if not m or not os.path.exists(d + "/eval.json"):
            continue
        ch = [l.strip().split(",") for l in open(d + "/metrics.csv") if ",check," in l]
        ds = [(float(c[3]), int(c[2])) for c in ch]
        eps = sum(1 for l in open(d + "/metrics.csv") if ",train," in l)
        f = json.load(open(d + "/eval.json"))["methods"][0]["final_policy"]["percent_of_road"]
        if curves:
            for dist, step in ds:
                print(f"{name},{m.group(1)},{m.group(2)},{step},{dist:.1f}")
            continue
        best = max(ds)
        if f < 90:
            below += 1
            drift += best[0] >= 999.9 and ds[-1][0] < 999.9
        print(f"{os.path.basename(d)} episodes {eps} best check {best[0]:.0f} m at {best[1]} "
              f"last {ds[-1][0]:.0f} final {f:.1f}")
    if not curves:
        print(f"{name}: {below} runs below 90%, {drift} of them with a 1000 m check and a lower last one")
