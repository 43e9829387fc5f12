#!/usr/bin/env python3
"""drive_paired_runs.py RUNS_DIR BASE NAME [SEEDS]: RED's final policy of the runs
RUNS_DIR/NAME-DEMO-sK against the runs RUNS_DIR/BASE-DEMO-sK of the same demo and seed (both
made by `red-cli drive --demo D --methods red --seed K --name X-DEMO-sK --out-dir RUNS_DIR
--train-config C`; DEMO is `scripted` or sN, e.g. s80 for a demo of track seed 80; NAME and
BASE without a dash). One table row per
demo and setting, then the paired differences (NAME minus BASE) with their standard errors,
per demo and over all pairs. SEEDS: "0 1 2 3 4" by default. A pair is counted only when both
runs have an eval.json; the table rows are each setting's finished runs. Runs evaluated on no
unseen roads show `-` there and pair on the demo's road only."""
import json, math, os, re, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from drive_table import pct  # noqa: E402  (the same reading of an eval.json entry)

if len(sys.argv) < 4:
    sys.exit(__doc__)
root, base, name = sys.argv[1:4]
seeds = [int(s) for s in (sys.argv[4] if len(sys.argv) > 4 else "0 1 2 3 4").split()]


def final(setting, demo, seed):
    p = os.path.join(root, f"{setting}-{demo}-s{seed}", "eval.json")
    if not os.path.isfile(p):
        return None
    red = [m for m in json.load(open(p))["methods"] if m["method"] == "red"]
    if not red:
        return None
    f = red[0]["final_policy"]
    return pct(f, "road"), pct(f, "unseen")


def mean_se(x):
    n = len(x)
    m = sum(x) / n
    s = math.sqrt(sum((v - m) ** 2 for v in x) / (n - 1) / n) if n > 1 else float("nan")
    return m, s


demos = sorted({m.group(1) for d in os.listdir(root)
                for m in [re.fullmatch(re.escape(name) + r"-(scripted|s\d+)-s\d+", d)] if m})
fmt = lambda xs: ", ".join("-" if x is None else f"{x:.1f}" for x in xs)
print("| setting | demo | seeds | % demo road | mean | worst | % unseen roads | mean |")
print("|---|---|---|---|---|---|---|---|")
pairs = {}
for demo in demos:
    got = {s: [final(s, demo, k) for k in seeds] for s in (base, name)}
    both = [i for i in range(len(seeds)) if got[base][i] and got[name][i]]
    pairs[demo] = [(got[name][i], got[base][i]) for i in both]
    for s in (base, name):
        r = [g[0] if g else None for g in got[s]]
        u = [g[1] if g else None for g in got[s]]
        rv = [x for x in r if x is not None]
        uv = [x for x in u if x is not None]
        if rv:
            um = f"{sum(uv)/len(uv):.1f}" if uv else "-"
            print(f"| {s} | {demo} | {' '.join(map(str, seeds))} | {fmt(r)} | {sum(rv)/len(rv):.1f} | "
                  f"{min(rv):.1f} | {fmt(u)} | {um} |")
print()
print(f"paired {name} - {base}: demo road, unseen roads (s.e.)")
everything = []
for demo, ps in list(pairs.items()) + [("all", None)]:
    ps = ps if ps is not None else everything
    if not ps:
        continue
    dr = mean_se([a[0] - b[0] for a, b in ps])
    ud = [a[1] - b[1] for a, b in ps if a[1] is not None and b[1] is not None]
    du = f"{mean_se(ud)[0]:+.1f} ({mean_se(ud)[1]:.1f})" if ud else "-"
    print(f"{demo}: {len(ps)} pairs, {dr[0]:+.1f} ({dr[1]:.1f}), {du}")
    if demo != "all":
        everything += ps
