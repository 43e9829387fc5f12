#!/usr/bin/env python3
"""drive_paired.py RUNS_DIR NAME [SEEDS] [METHOD]: a method's final-policy table of the
runs RUNS_DIR/NAME-DEMO-sK (DEMO: scripted, s11, s23, s37; made by `red-cli drive --demo D
--methods METHOD --seed K --name NAME-DEMO-sK --out-dir RUNS_DIR --train-config C`) and its
paired difference against the same method at the session-32 defaults (docs/results/drive.md,
"The defaults since session 32": RED on seeds 0-9, AE, GAIL and GMMIL on seeds 0-4), as
sessions 34 and 35 computed them. SEEDS: "0 1 2 3 4" by default; METHOD: red (default), ae,
gail or gmmil; or red@37: RED against the defaults since session 37 (the Polyak-averaged
policy, session 34's runs of it on seeds 0-9); or g98@39: RED with the discount 0.98
(session 39's runs, seeds 0-9); or ae@37, gail@37, gmmil@37: that method against its own
runs at the defaults since session 37 (seeds 0-4); red@42: RED against the defaults since
session 42 (seeds 0-9); ae@42, gail@42, gmmil@42: that method against its runs at the
defaults since session 42 (seeds 0-4); red@45: RED against the defaults since session 45
(seeds 0-9, and 10-14 from session 52's runs); red@59: RED against the defaults since
session 59 (red@45 but for s37, whose runs are session 58's `lc60` runs on seeds 0-4 and
10-14).""" 
import json, os, sys, math
D = {  # (demo road per seed 0-9, unseen per seed 0-9)
 "scripted": ([100.0,100.0,100.0,100.0,84.0,70.9,61.5,100.0,64.9,100.0],[54.4,90.8,96.3,92.5,70.9,35.1,57.2,75.4,37.8,94.8]),
 "s11": ([79.7,63.5,83.8,100.0,77.3,100.0,87.0,100.0,100.0,83.5],[77.1,43.4,66.8,83.4,41.7,63.2,63.0,86.7,75.6,79.2]),
 "s23": ([100.0,65.7,100.0,80.8,100.0,80.6,100.0,73.3,100.0,100.0],[92.5,70.8,63.5,63.4,92.6,69.6,83.4,82.7,76.5,92.0]),
 "s37": ([100.0,44.5,100.0,82.0,63.0,100.0,100.0,81.6,100.0,100.0],[100.0,44.6,73.9,91.2,61.9,100.0,100.0,50.9,100.0,87.8]),
}
# The other methods at the session-32 defaults, seeds 0-4 (GMMIL: session 33).
BASE = {
 "ae": {"scripted": ([81.5,100.0,100.0,100.0,58.9],[57.5,96.3,57.3,47.4,44.0]),
        "s11": ([94.9,100.0,76.0,95.4,77.1],[46.0,56.5,29.3,49.7,28.2]),
        "s23": ([67.3,72.4,82.7,51.8,51.8],[71.0,69.8,87.1,61.0,49.3]),
        "s37": ([81.5,100.0,100.0,100.0,84.6],[83.6,34.1,71.4,15.8,31.0])},
 "gail": {"scripted": ([100.0,14.0,100.0,61.5,100.0],[89.8,12.4,67.9,52.1,47.1]),
          "s11": ([16.0,41.0,61.6,37.0,47.5],[40.8,27.1,51.9,31.4,39.1]),
          "s23": ([52.3,59.3,61.6,26.9,79.8],[57.1,69.2,50.1,44.3,51.2]),
          "s37": ([69.3,50.1,100.0,100.0,97.1],[18.9,22.3,15.0,15.8,16.1])},
 "gmmil": {"scripted": ([66.7,100.0,100.0,31.6,87.2],[42.2,55.4,31.4,22.3,39.7]),
           "s11": ([28.7,67.8,83.8,77.9,66.9],[31.9,39.4,32.9,36.4,47.1]),
           "s23": ([21.5,80.8,21.3,68.0,42.4],[54.5,74.6,52.6,65.3,68.0]),
           "s37": ([100.0,100.0,81.5,100.0,81.5],[17.6,15.8,15.2,15.8,15.2])},
}
# RED at the defaults since session 37 (svg.policy_avg_tau 1e-4), session 34's runs.
BASE["red@37"] = {
 "scripted": ([100.0]*10,[65.7,98.5,97.3,87.5,86.1,48.3,77.6,69.5,46.7,93.3]),
 "s11": ([87.8,77.1,81.9,100.0,77.6,90.6,77.6,100.0,100.0,85.1],[70.8,53.8,63.4,70.5,44.2,61.2,62.0,68.8,70.7,75.3]),
 "s23": ([100.0,76.3,100.0,80.9,100.0,80.7,100.0,79.7,100.0,100.0],[96.6,85.0,65.2,56.8,72.9,72.1,93.3,84.2,81.9,86.7]),
 "s37": ([100.0,44.5,100.0,100.0,63.0,100.0,100.0,100.0,100.0,100.0],[87.9,46.1,50.1,76.6,86.9,100.0,100.0,81.7,100.0,100.0]),
}
# RED with the discount 0.98 ({"svg":{"gamma":0.98}}), session 39's runs (docs/results/drive.md).
BASE["g98@39"] = {
 "scripted": ([78.7,100.0,100.0,100.0,100.0,100.0,100.0,31.6,84.5,100.0],[95.2,97.7,84.7,91.4,91.8,94.6,83.5,51.0,74.1,77.0]),
 "s11": ([88.0,100.0,71.6,100.0,66.0,79.7,85.1,88.0,83.5,100.0],[37.4,92.6,54.8,82.4,72.0,49.4,80.4,80.6,79.0,100.0]),
 "s23": ([100.0,100.0,83.2,100.0,100.0,100.0,81.5,82.9,81.1,100.0],[94.1,96.3,69.7,89.7,57.7,80.3,85.2,92.3,89.6,75.1]),
 "s37": ([100.0,63.1,81.5,100.0,100.0,100.0,65.3,63.0,100.0,100.0],[65.1,79.3,46.5,91.7,97.0,36.8,83.6,92.6,31.1,86.9]),
}
# AE, GAIL and GMMIL at the defaults since session 37 (seeds 0-4, section "The defaults since
# session 37" of docs/results/drive.md).
BASE["ae@37"] = {
 "scripted": ([100.0,100.0,100.0,100.0,100.0],[66.1,100.0,56.9,48.5,40.5]),
 "s11": ([90.2,85.2,40.7,85.9,77.4],[47.1,49.7,28.3,51.8,33.6]),
 "s23": ([62.0,59.0,70.4,62.1,59.2],[71.2,66.3,69.2,64.4,65.6]),
 "s37": ([100.0,100.0,100.0,100.0,100.0],[76.0,70.6,33.7,15.8,30.2]),
}
BASE["gail@37"] = {
 "scripted": ([100.0,37.4,100.0,61.5,100.0],[96.3,27.3,74.8,55.4,45.3]),
 "s11": ([72.3,49.4,49.1,30.7,50.7],[52.3,37.3,44.3,26.4,42.3]),
 "s23": ([49.2,55.7,52.5,39.3,87.1],[53.4,69.9,53.4,52.3,58.2]),
 "s37": ([87.6,50.8,100.0,100.0,100.0],[22.2,19.4,16.6,15.8,15.8]),
}
BASE["gmmil@37"] = {
 "scripted": ([83.3,100.0,100.0,100.0,83.3],[45.7,41.9,40.1,45.8,35.7]),
 "s11": ([33.7,79.7,87.8,78.8,66.9],[34.1,34.8,32.8,35.6,41.5]),
 "s23": ([44.5,80.9,60.9,68.7,67.2],[51.3,74.8,66.0,60.9,64.6]),
 "s37": ([100.0,100.0,100.0,100.0,81.5],[15.5,15.8,15.8,15.8,15.2]),
}
# RED at the defaults since session 42 (discount 0.98, 10-step targets, stall end), seeds 0-9.
BASE["red@42"] = {
 "scripted": ([100.0,100.0,100.0,100.0,100.0,100.0,100.0,81.5,100.0,100.0],[92.1,90.5,98.5,100.0,95.2,100.0,91.9,82.3,91.8,44.3]),
 "s11": ([100.0,100.0,100.0,100.0,100.0,70.2,100.0,91.9,100.0,81.5],[94.1,98.5,92.1,93.7,86.2,42.9,100.0,81.8,95.9,83.4]),
 "s23": ([100.0,100.0,89.4,88.0,80.6,66.5,100.0,100.0,100.0,80.8],[78.9,92.9,97.1,79.0,72.9,96.1,88.9,100.0,87.5,76.8]),
 "s37": ([60.6,100.0,100.0,100.0,100.0,76.6,100.0,81.8,74.1,100.0],[47.7,50.1,69.0,87.2,100.0,74.7,98.4,90.3,57.8,97.5]),
}
# AE, GAIL and GMMIL at the defaults since session 42, seeds 0-4 (session 42's runs).
BASE["ae@42"] = {
 "scripted": ([100.0,100.0,100.0,100.0,81.8],[100.0,100.0,94.8,71.2,56.7]),
 "s11": ([95.0,75.9,65.3,88.5,53.1],[62.7,68.8,37.5,59.3,42.3]),
 "s23": ([100.0,82.0,67.2,100.0,100.0],[71.8,96.4,79.1,88.9,69.1]),
 "s37": ([63.0,100.0,100.0,89.4,82.4],[31.2,67.1,95.7,85.7,40.7]),
}
BASE["gail@42"] = {
 "scripted": ([46.9,100.0,46.4,95.0,81.6],[83.0,70.2,45.1,38.8,74.7]),
 "s11": ([65.2,100.0,100.0,38.9,64.9],[54.6,56.7,77.9,29.2,40.7]),
 "s23": ([82.8,85.9,100.0,79.6,100.0],[79.3,91.2,82.0,50.9,67.7]),
 "s37": ([100.0,100.0,63.0,100.0,100.0],[23.5,15.8,49.3,15.2,15.8]),
}
BASE["gmmil@42"] = {
 "scripted": ([29.7,81.5,57.7,100.0,100.0],[34.5,34.1,37.4,50.6,48.2]),
 "s11": ([79.8,85.4,67.3,73.5,79.7],[44.5,42.0,40.9,37.2,42.1]),
 "s23": ([64.7,77.1,66.3,48.1,85.6],[64.9,65.3,70.6,70.1,77.2]),
 "s37": ([100.0,56.8,100.0,100.0,100.0],[14.4,15.2,15.8,73.7,14.4]),
}
# RED at the defaults since session 45 (logarithmic tails on the policy's input), seeds 0-9.
BASE["red@45"] = {
 "scripted": ([100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0,100.0],[87.1,89.4,98.0,88.8,100.0,97.0,92.6,100.0,91.1,100.0,100.0,97.0,100.0,71.1,85.6]),
 "s11": ([100.0,100.0,100.0,100.0,100.0,100.0,81.5,100.0,95.9,100.0,100.0,100.0,100.0,100.0,100.0],[95.3,92.6,96.2,87.8,100.0,69.0,67.9,89.1,87.0,86.9,83.4,78.2,91.1,91.7,94.5]),
 "s23": ([80.9,83.2,100.0,92.6,100.0,87.4,83.2,100.0,100.0,80.9,81.5,81.8,100.0,100.0,89.6],[72.2,96.4,97.8,69.5,91.3,74.5,76.6,85.0,79.1,83.6,76.9,52.8,85.6,99.1,67.3]),
 "s37": ([100.0,100.0,100.0,100.0,100.0,65.9,100.0,77.8,100.0,80.7,81.5,100.0,46.6,86.0,100.0],[53.0,93.4,86.8,96.5,46.6,87.6,100.0,55.0,74.4,26.9,90.0,99.7,41.2,90.8,99.1]),
}
# RED at the defaults since session 59 (lane shifts for a demonstration that keeps one lane):
# the scripted, s11 and s23 demos train as at the session-45 defaults; s37 is session 58's
# `lc60` runs (docs/results/drive/s58-lane-shift-runs.csv, seeds 0-4 and 10-14; none on 5-9).
BASE["red@59"] = dict(BASE["red@45"])
BASE["red@59"]["s37"] = (
 [100.0,100.0,100.0,100.0,100.0] + [None] * 5 + [100.0,100.0,92.4,100.0,100.0],
 [77.8,98.4,97.4,88.9,54.8] + [None] * 5 + [100.0,77.8,91.9,100.0,76.5],
)
root, name = sys.argv[1], sys.argv[2]
method = sys.argv[4] if len(sys.argv) > 4 else "red"
if method != "red":
    D = BASE[method]
    method = method.split("@")[0]
    if method not in ("ae", "gail", "gmmil"):
        method = "red"  # red@37, g98@39: RED under other settings
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
        m = [m for m in e["methods"] if m["method"] == method][0]["final_policy"]
        r.append(m["percent_of_road"]); u.append(m["unseen_roads"]["percent_of_road"])
    done = [i for i, x in enumerate(r) if x is not None]
    f = lambda xs: ", ".join("-" if x is None else f"{x:.1f}" for x in xs)
    if done:
        rv = [r[i] for i in done]; uv = [u[i] for i in done]
        print(f"| {name} | {demo} | {seeds[0]}-{seeds[-1]} | {f(r)} | {sum(rv)/len(rv):.1f} | {min(rv):.1f} | {f(u)} | {sum(uv)/len(uv):.1f} |")
    for i in done:
        k = seeds[i]
        if road[k] is None:
            continue  # no baseline run on this seed
        dr.append(r[i]); du.append(u[i]); dd.append(r[i] - road[k]); ddu.append(u[i] - unseen[k])
        n90 += r[i] >= 90; n90d += road[k] >= 90
def ms(x):
    n = len(x); m = sum(x)/n
    s = math.sqrt(sum((v-m)**2 for v in x)/(n-1)/n) if n > 1 else float('nan')
    return m, s
if dr:
    print(f"\n{len(dr)} runs: demo road {ms(dr)[0]:.1f} (default {ms([a-b for a,b in zip(dr,dd)])[0]:.1f}), paired {ms(dd)[0]:+.1f} (s.e. {ms(dd)[1]:.1f});"
          f" unseen {ms(du)[0]:.1f} (default {ms([a-b for a,b in zip(du,ddu)])[0]:.1f}), paired {ms(ddu)[0]:+.1f} (s.e. {ms(ddu)[1]:.1f}); runs >= 90%: {n90} (default {n90d})")
