#!/usr/bin/env python3
"""One table across the runs of `red-cli drive` (one run folder per training
seed): per method, the FINAL policy's % of the demo's road and of the unseen
roads per seed, their mean and the worst seed; the policy selected by the
method's own reward beside it, labelled.

    python3 scripts/drive_table.py runs/drive-s0 runs/drive-s1 ...
"""
import json
import os
import sys


def pct(p, key):
    if p is None:
        return None
    if key == "road":
        return p["percent_of_road"]
    u = p.get("unseen_roads")
    return None if u is None else u["percent_of_road"]


def fmt(v):
    return "-" if v is None else f"{v:.1f}"


def main(dirs):
    runs = []
    for d in dirs:
        path = os.path.join(d, "eval.json")
        if not os.path.exists(path):
            print(f"(skipped {d}: no eval.json yet)", file=sys.stderr)
            continue
        with open(path) as f:
            runs.append((d, json.load(f)))
    if not runs:
        sys.exit("no finished run")
    label = runs[0][1].get("demo_label", "expert")
    methods = [m["method"] for m in runs[0][1]["methods"]]
    print(f"{len(runs)} seed(s): " + ", ".join(os.path.basename(d) for d, _ in runs))
    print(f"{label}: {runs[0][1]['expert_distance']:.1f} m of {runs[0][1]['road_length']:.0f} m; "
          f"{runs[0][1]['eval_runs']} deterministic runs per road; unseen roads: "
          f"{len(runs[0][1]['unseen_track_seeds'])}")
    print()
    print("| method | policy | % demo road per seed | mean | worst | % unseen roads per seed | mean | worst |")
    print("|---|---|---|---:|---:|---|---:|---:|")
    for m in methods:
        for which, title in (("final_policy", "final"), ("selected_by_own_reward", "selected by own reward")):
            rows = []
            for _, e in runs:
                mm = next(x for x in e["methods"] if x["method"] == m)
                rows.append(mm.get(which))
            if all(r is None for r in rows):
                continue
            road = [pct(r, "road") for r in rows]
            unseen = [pct(r, "unseen") for r in rows]
            def agg(xs):
                xs = [x for x in xs if x is not None]
                if not xs:
                    return "-", "-"
                return f"{sum(xs) / len(xs):.1f}", f"{min(xs):.1f}"
            rm, rw = agg(road)
            um, uw = agg(unseen)
            print(f"| {m} | {title} | {', '.join(fmt(x) for x in road)} | {rm} | {rw} | "
                  f"{', '.join(fmt(x) for x in unseen)} | {um} | {uw} |")


if __name__ == "__main__":
    main(sys.argv[1:])
