#!/usr/bin/env python3
"""drive_lane_choice.py [--starts N] [--step K] [--bin PATH] ROAD RUN_DIR...: where each saved
final RED policy is at step K (44 by default, about 60 m in) from N deterministic starts
(reset seeds 1000, 1001, ...; 100 by default) on road ROAD (track seed), through
`drive_trace` (`cargo build --release -p red-experiments --example drive_trace`;
--bin to give another build). A start counts as "up" if the car is more than 1 m to the left
of the road's centre line then (at its last step, if it ended before), "down" if more than
1 m to the right, else "mid" (still in the middle lane; a car astride a lane line counts on
its side). drive_trace prints the offset to 0.1 m. Prints one CSV row per run: the starts on
each side, and on each side those that end before 150 m and before the road's end (the
run's `road_length`)."""
import json, os, subprocess, sys

args = sys.argv[1:]
starts, step, binary = 100, 44, "target/release/examples/drive_trace"
while args and args[0].startswith("--"):
    flag, value = args[0], args[1]
    args = args[2:]
    if flag == "--starts":
        starts = int(value)
    elif flag == "--step":
        step = int(value)
    elif flag == "--bin":
        binary = value
    else:
        sys.exit(f"unknown flag {flag}; see the docstring")
if len(args) < 2:
    sys.exit(__doc__)
road, runs = args[0], args[1:]
seeds = ",".join(str(1000 + i) for i in range(starts))
sides = ("up", "mid", "down")
print("run," + ",".join(f"{s},{s}_end_before_150m,{s}_end_before_road_end" for s in sides))
for run in runs:
    out = subprocess.run(
        [binary, run, road, seeds, str(step + 1)],
        env={**{k: v for k, v in os.environ.items() if k != "TRACE_RAYS"}, "TRACE_EVERY": "1"},
        capture_output=True, text=True, check=True,
    ).stdout.splitlines()
    count = {s: [0, 0, 0] for s in sides}
    road_length = json.load(open(os.path.join(run, "config.json")))["drive"]["road_length"]
    # Each start: a header line "road R seed S: start ... -> D m" and a line of y/steer/pedal.
    heads, traces = out[0::2], out[1::2]
    if len(heads) != starts or not all(h.startswith(f"road {road} seed ") for h in heads):
        sys.exit(f"{run}: drive_trace printed {len(out)} lines, not a header and a trace per start")
    for head, trace in zip(heads, traces):
        dist = float(head.split("->")[1].split()[0])
        # Steps 0..=step, or fewer if the episode ended before.
        y = float(trace.split()[-1].split("/")[0])
        side = "up" if y > 1.0 else ("down" if y < -1.0 else "mid")
        c = count[side]
        c[0] += 1
        c[1] += dist < 150.0
        c[2] += dist < road_length
    name = os.path.basename(os.path.normpath(run))
    print(name + "," + ",".join(",".join(str(v) for v in count[s]) for s in sides))
