#!/usr/bin/env python3
"""drive_many_starts.py [--starts N] [--bin PATH] RUN_DIR...: drives each finished driving
run's saved final RED policy from N deterministic starts per road (reset seeds 1000, 1001,
...; the first 5 are the evaluation's) on the demo's road and the run's unseen roads, through
`target/release/examples/drive_eval_saved --runs N`, and prints one CSV row per run: the %
of the demo's road over the evaluation's 5 starts and over all N, the finishes and crashes of
the N (and those that ran out of time), the same % for the unseen roads, and the reset seeds (minus 1000) that crash on the
demo's road. Then, per demo, the runs at >= 90% of the demo's road by the first 5 and by all
N starts. Build first: `cargo build --release -p red-experiments --example drive_eval_saved`.

drive_many_starts.py --compare BASE.csv NEW.csv: pairs two such CSVs by (demo, seed) (runs
named NAME-DEMO-sK) and prints, for each setting name in NEW, the runs paired, the means and
the paired difference (standard error) of the demo's road and of unseen roads, over the
first 5 starts and over all N, and the runs at >= 90% of the demo's road by each.
"""
import json, os, re, subprocess, sys
from collections import defaultdict

args = sys.argv[1:]

def compare(base_path, new_path):
    import csv, math
    def load(p):
        out = {}
        for r in csv.DictReader(open(p)):
            m = re.match(r"(.+?)-(scripted|s\d+)-s(\d+)$", r["run"])
            if not m:
                print(f"# {p}: skipped {r['run']} (not NAME-DEMO-sK)", file=sys.stderr)
                continue
            key = (m.group(1), m.group(2), int(m.group(3)))
            if key in out:
                sys.exit(f"{p}: run {r['run']} appears twice")
            out[key] = r
        return out
    base, new = load(base_path), load(new_path)
    if len({k[0] for k in base}) > 1:
        sys.exit(f"{base_path} holds several settings ({', '.join(sorted({k[0] for k in base}))}); "
                 "give a BASE of one setting")
    if {r["starts"] for r in base.values()} != {r["starts"] for r in new.values()}:
        print("# warning: the two files drove different numbers of starts", file=sys.stderr)
    cols = ["demo_road_pct_first5", "demo_road_pct_all", "unseen_pct_first5", "unseen_pct_all"]
    for name in sorted({k[0] for k in new}):
        pairs = []
        for (n, demo, seed), r in new.items():
            b = [v for (bn, bd, bs), v in base.items() if bd == demo and bs == seed]
            if n == name and b:
                pairs.append((b[0], r))
        if not pairs:
            print(f"{name}: no run paired with {base_path}")
            continue
        print(f"{name}: {len(pairs)} runs paired with {base_path}")
        for c in cols:
            d = [float(r[c]) - float(b[c]) for b, r in pairs]
            mean = sum(d) / len(d)
            se = math.sqrt(sum((x - mean) ** 2 for x in d) / (len(d) - 1) / len(d)) if len(d) > 1 else float("nan")
            print(f"  {c:22s} base {sum(float(b[c]) for b, _ in pairs) / len(pairs):5.1f}  "
                  f"new {sum(float(r[c]) for _, r in pairs) / len(pairs):5.1f}  "
                  f"paired {mean:+5.1f} (s.e. {se:.1f})")
        for c in cols[:2]:
            print(f"  runs >= 90% by {c}: base {sum(float(b[c]) >= 90 for b, _ in pairs)}, "
                  f"new {sum(float(r[c]) >= 90 for _, r in pairs)}")

if args[:1] == ["--compare"]:
    if len(args) != 3:
        sys.exit(__doc__)
    compare(args[1], args[2])
    sys.exit(0)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from drive_flags import eval_saved_options  # noqa: E402  (read alike by the drive scripts)

starts, binary = eval_saved_options(args, __doc__)

def pct(dists, road):
    return 100.0 * sum(min(d, road) for d in dists) / (road * len(dists))

print("run,demo_road_pct_first5,demo_road_pct_all,starts,finishes,crashes,time_up,"
      "unseen_pct_first5,unseen_pct_all,demo_road_crash_starts")
per_demo = defaultdict(lambda: [0, 0, 0])
for run in args:
    done = subprocess.run([binary, "--runs", str(starts), run], capture_output=True, text=True)
    if done.returncode != 0:
        print(f"# skipped {run}: {binary} failed: {done.stderr.strip()}", file=sys.stderr)
        continue
    out = done.stdout
    road = json.load(open(os.path.join(run, "config.json")))["drive"]["road_length"]
    demo, unseen = None, []
    for line in out.splitlines():
        m = re.match(r"road (\d+)( \(the demonstration's\))?: ([\d.]+)% \| (.*)$", line)
        if not m:
            continue
        eps = m.group(4).split(" | ")
        dists = [float(e.split()[0]) for e in eps]
        ends = [e.split()[1] for e in eps]
        if not dists or len(dists) != starts:
            sys.exit(f"{run}: expected {starts} episodes on road {m.group(1)}, got {len(dists)}")
        row = (pct(dists[:5], road), pct(dists, road), ends)
        if m.group(2):
            demo = row
        else:
            unseen.append(row)
    if demo is None:
        sys.exit(f"{run}: no line for the demo's road in drive_eval_saved's output")
    first5_u = sum(u[0] for u in unseen) / len(unseen) if unseen else float("nan")
    all_u = sum(u[1] for u in unseen) / len(unseen) if unseen else float("nan")
    crashes = [i for i, e in enumerate(demo[2]) if e == "crash"]
    print(f"{os.path.basename(run.rstrip('/'))},{demo[0]:.1f},{demo[1]:.1f},{starts},"
          f"{demo[2].count('finish')},{len(crashes)},{demo[2].count('time')},"
          f"{first5_u:.1f},{all_u:.1f},"
          f"{' '.join(map(str, crashes))}")
    key = re.sub(r"-s\d+$", "", os.path.basename(run.rstrip("/")))
    per_demo[key][0] += 1
    per_demo[key][1] += demo[0] >= 90.0
    per_demo[key][2] += demo[1] >= 90.0
for key, (n, a, b) in sorted(per_demo.items()):
    print(f"# {key}: {n} runs; >= 90% of the demo's road: {a} by the first 5 starts, "
          f"{b} by all {starts}", file=sys.stderr)
