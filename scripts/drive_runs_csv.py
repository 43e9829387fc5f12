#!/usr/bin/env python3
"""drive_runs_csv.py RUNS_DIR NAME...: one CSV row per finished run RUNS_DIR/NAME-DEMO-sK
(DEMO: scripted, s11, s23, s37; made by `red-cli drive --demo D --methods red --seed K --name
NAME-DEMO-sK --out-dir RUNS_DIR --train-config C`): RED's final policy's % of the demo's road
and of the unseen roads (the run's deterministic evaluation starts per road, 5 by default,
from eval.json), and the same for the policy selected by RED's own reward, as the
docs/results/drive/sNN-*-runs.csv files hold them; `-` where the run has no such number (no
selection checks, no unseen roads). Runs not finished yet (no eval.json) or without RED are
left out with a note on stderr."""
import json, os, re, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from drive_table import pct  # noqa: E402  (the same reading of an eval.json entry)

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
        red = [x for x in json.load(open(path))["methods"] if x["method"] == "red"]
        if not red:
            print(f"# {d}: no RED in eval.json, left out", file=sys.stderr)
            continue
        f, s = red[0].get("final_policy"), red[0].get("selected_by_own_reward")
        rows.append((order.get(m.group(1), 9), m.group(1), int(m.group(2)),
                     pct(f, "road"), pct(f, "unseen"), pct(s, "road"), pct(s, "unseen")))
    for _, demo, seed, *v in sorted(rows):
        print(f"{name},{demo},{seed}," + ",".join("-" if x is None else f"{x:.1f}" for x in v))
