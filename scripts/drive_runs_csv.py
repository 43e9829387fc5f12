#!/usr/bin/env python3
"""drive_runs_csv.py RUNS_DIR NAME...: one CSV row per finished run RUNS_DIR/NAME-DEMO-sK
(DEMO: scripted, s11, s23, s37; made by `red-cli drive --demo D --methods red --seed K --name
NAME-DEMO-sK --out-dir RUNS_DIR --train-config C`): RED's final policy's % of the demo's road
and of the unseen roads (5 deterministic starts per road, from eval.json), and the same for
the policy selected by RED's own reward, as the docs/results/drive/sNN-*-runs.csv files hold
them. Runs not finished yet (no eval.json) are left out with a note on stderr."""
import json, os, re, sys

if len(sys.argv) < 3:
    sys.exit(__doc__)
root, names = sys.argv[1], sys.argv[2:]
order = {"scripted": 0, "s11": 1, "s23": 2, "s37": 3}
print("setting,demo,seed,final_demo_road_pct,final_unseen_pct,selected_demo_road_pct,selected_unseen_pct")
for name in names:
    rows = []
    for d in os.listdir(root):
        m = re.fullmatch(re.escape(name) + r"-(scripted|s\d+)-s(\d+)", d)
        if not m:
            continue
        path = os.path.join(root, d, "eval.json")
        if not os.path.isfile(path):
            print(f"# {d}: no eval.json yet, left out", file=sys.stderr)
            continue
        red = [x for x in json.load(open(path))["methods"] if x["method"] == "red"][0]
        f, s = red["final_policy"], red["selected_by_own_reward"]
        rows.append((order.get(m.group(1), 9), m.group(1), int(m.group(2)),
                     f["percent_of_road"], f["unseen_roads"]["percent_of_road"],
                     s["percent_of_road"], s["unseen_roads"]["percent_of_road"]))
    for _, demo, seed, a, b, c, e in sorted(rows):
        print(f"{name},{demo},{seed},{a:.1f},{b:.1f},{c:.1f},{e:.1f}")
