#!/usr/bin/env python3
"""drive_paired.py RUNS_DIR NAME [SEEDS]: RED's final-policy table of the runs
RUNS_DIR/NAME-DEMO-sK (DEMO: scripted, s11, s23, s37; made by `red-cli drive --demo D
--methods red --seed K --name NAME-DEMO-sK --out-dir RUNS_DIR --train-config C`) and its
paired difference
against the session-32 default (docs/results/drive.md, the table "The defaults since
session 32"), as session 34 computed them. SEEDS: "0 1 2 3 4" by default."""
import json, os, sys, math
D = {  # (demo road per seed 0-9, unseen per seed 0-9)
 "scripted": ([100.0,100.0,100.0,100.0,84.0,70.9,61.5,100.0,64.9,100.0],[54.4,90.8,96.3,92.5,70.9,35.1,57.2,75.4,37.8,94.8]),
 "s11": ([79.7,63.5,83.8,100.0,77.3,100.0,87.0,100.0,100.0,83.5],[77.1,43.4,66.8,83.4,41.7,63.2,63.0,86.7,75.6,79.2]),
 "s23": ([100.0,65.7,100.0,80.8,100.0,80.6,100.0,73.3,100.0,100.0],[92.5,70.8,63.5,63.4,92.6,69.6,83.4,82.7,76.5,92.0]),
 "s37": ([100.0,44.5,100.0,82.0,63.0,100.0,100.0,81.6,100.0,100.0],[100.0,44.6,73.9,91.2,61.9,100.0,100.0,50.9,100.0,87.8]),
}
root, name = sys.argv[1], sys.argv[2]
seeds = [int(s) for s in (sys.argv[3] if len(sys.argv) > 3 else "0 1 2 3 4").split()]
dr, du, dd, ddu, n90, n90d = [], [], [], [], 0, 0
print(f"| setting | demo | seeds | % demo road | mean | worst | % unseen roads | mean |")
for demo, (road, unseen) in D.items():
    r, u = [], []
    for k in seeds:
        p = os.path.join(root, f"{name}-{demo}-s{k}", "eval.json")
        if not os.path.exists(p):
            r.append(None); u.append(None); continue
        e = json.load(open(p))
        m = [m for m in e["methods"] if m["method"] == "red"][0]["final_policy"]
        r.append(m["percent_of_road"]); u.append(m["unseen_roads"]["percent_of_road"])
    done = [i for i, x in enumerate(r) if x is not None]
    f = lambda xs: ", ".join("-" if x is None else f"{x:.1f}" for x in xs)
    if done:
        rv = [r[i] for i in done]; uv = [u[i] for i in done]
        print(f"| {name} | {demo} | {seeds[0]}-{seeds[-1]} | {f(r)} | {sum(rv)/len(rv):.1f} | {min(rv):.1f} | {f(u)} | {sum(uv)/len(uv):.1f} |")
    for i in done:
        k = seeds[i]
        dr.append(r[i]); du.append(u[i]); dd.append(r[i] - road[k]); ddu.append(u[i] - unseen[k])
        n90 += r[i] >= 90; n90d += road[k] >= 90
def ms(x):
    n = len(x); m = sum(x)/n
    s = math.sqrt(sum((v-m)**2 for v in x)/(n-1)/n) if n > 1 else float('nan')
    return m, s
if dr:
    print(f"\n{len(dr)} runs: demo road {ms(dr)[0]:.1f} (default {ms([a-b for a,b in zip(dr,dd)])[0]:.1f}), paired {ms(dd)[0]:+.1f} (s.e. {ms(dd)[1]:.1f});"
          f" unseen {ms(du)[0]:.1f} (default {ms([a-b for a,b in zip(du,ddu)])[0]:.1f}), paired {ms(ddu)[0]:+.1f} (s.e. {ms(ddu)[1]:.1f}); runs >= 90%: {n90} (default {n90d})")
