#!/usr/bin/env python3
"""drive_bar_odds.py [--starts N] [--bin PATH] RUN_DIR...: how likely each finished driving
run's saved final RED policy is to meet issue 17's per-seed bar (at least 90% of the demo's
road over 5 starts) from 5 fresh starts rather than the evaluation's fixed ones. Drives the
policy from N deterministic starts on the demo's road (reset seeds 1000, 1001, ...; through
`drive_eval_saved --runs N --roads ROAD`) and takes the 5 starts as drawn independently from
those N (each start's distance equally likely): the chance is exact for that distribution
(distances in whole decimetres, as drive_eval_saved prints them). Prints a CSV row per run
(its % over the N starts, its crashes, the chance), then on stderr, per setting and demo, the
expected number of runs that miss and the chance that none does, and the same over every run
of the setting (runs not named NAME-DEMO-sK are left out of these, with a note). Build first: `cargo build --release -p red-experiments --example
drive_eval_saved`."""
import json, os, re, subprocess, sys
from collections import defaultdict

args = sys.argv[1:]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from drive_flags import eval_saved_options  # noqa: E402  (read alike by the drive scripts)

starts, binary = eval_saved_options(args, __doc__)


def pass_chance(dists, road, draws=5, bar=90.0):
    """P(the mean share of the road over `draws` independent picks from `dists` (metres,
    each capped at `road`) >= bar %), exact on distances in whole decimetres."""
    # Shortfalls below the road's end in decimetres; the bar allows a total
    # of draws * road * (100 - bar) / 100 metres.
    allowed = round(draws * road * (100.0 - bar) / 100.0 * 10)
    weights = defaultdict(float)
    for d in dists:
        weights[round((road - min(d, road)) * 10)] += 1.0 / len(dists)
    dist = {0: 1.0}
    for _ in range(draws):
        nxt = defaultdict(float)
        for total, p in dist.items():
            for short, q in weights.items():
                if total + short <= allowed:
                    nxt[total + short] += p * q
        dist = nxt
    return min(sum(dist.values()), 1.0)


print("run,demo_road_pct_all,starts,crashes,pass_chance_5_fresh_starts")
groups = defaultdict(list)
for run in args:
    cfg = json.load(open(os.path.join(run, "config.json")))
    road, seed = cfg["drive"]["road_length"], cfg["drive"]["track_seed"]
    done = subprocess.run([binary, "--runs", str(starts), "--roads", str(seed), run],
                          capture_output=True, text=True)
    if done.returncode != 0:
        print(f"# skipped {run}: {binary} failed: {done.stderr.strip()}", file=sys.stderr)
        continue
    dists, ends = None, None
    for line in done.stdout.splitlines():
        m = re.match(r"road (\d+) \(the demonstration's\): ([\d.]+)% \| (.*)$", line)
        if m:
            eps = m.group(3).split(" | ")
            dists = [float(e.split()[0]) for e in eps]
            ends = [e.split()[1] for e in eps]
    if dists is None or len(dists) != starts:
        sys.exit(f"{run}: expected {starts} episodes on the demo's road (track seed {seed}) "
                 f"in drive_eval_saved's output")
    p = pass_chance(dists, road)
    name = os.path.basename(run.rstrip("/"))
    pct = 100.0 * sum(min(d, road) for d in dists) / (road * len(dists))
    print(f"{name},{pct:.1f},{starts},{ends.count('crash')},{p:.3f}")
    m = re.match(r"(.+?)-(scripted|s\d+)-s\d+$", name)
    if m:
        groups[(m.group(1), m.group(2))].append(p)
        groups[(m.group(1), "all")].append(p)
    else:
        print(f"# {name}: not NAME-DEMO-sK, left out of the summaries", file=sys.stderr)
for (setting, demo), ps in sorted(groups.items()):
    none_miss = 1.0
    for p in ps:
        none_miss *= p
    print(f"# {setting} {demo}: {len(ps)} runs, expected misses {sum(1 - p for p in ps):.2f}, "
          f"chance that none misses {none_miss:.3f}", file=sys.stderr)
