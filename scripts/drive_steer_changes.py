#!/usr/bin/env python3
"""drive_steer_changes.py ROAD RUN_DIR...: how much each saved final RED policy changes its
steering from one control step to the next. For each run folder, drives the evaluation's 5
starts (reset seeds 1000-1004) on track seed ROAD for up to 600 steps through
`target/release/examples/drive_trace` (TRACE_EVERY=1) and prints the mean over the starts of
the mean |steer_t - steer_(t-1)|. A demo file's own figure: --demo FILE.json.
Build first: `cargo build --release -p red-experiments --example drive_trace`.
"""
import json, os, subprocess, sys

TRACE = "target/release/examples/drive_trace"


def mean_change(steer):
    d = [abs(a - b) for a, b in zip(steer[1:], steer)]
    return sum(d) / len(d) if d else 0.0


def run_change(run, road):
    env = dict(os.environ, TRACE_EVERY="1")
    p = subprocess.run([TRACE, run, str(road), "1000,1001,1002,1003,1004", "600"],
                       env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{run}: drive_trace failed: {p.stderr.strip()}")
    per_start = [mean_change([float(t.split("/")[1]) for t in line.split()])
                 for line in p.stdout.splitlines() if line.startswith("   ")]
    return sum(per_start) / len(per_start)


args = sys.argv[1:]
if len(args) == 2 and args[0] == "--demo":
    for t in json.load(open(args[1]))["trajectories"]:
        print(f"{args[1]}: {mean_change([a[0] for a in t['actions']]):.3f}")
elif len(args) >= 2:
    for run in args[1:]:
        print(f"{os.path.basename(run.rstrip('/'))}: {run_change(run, int(args[0])):.3f}")
else:
    sys.exit(__doc__)
