#!/usr/bin/env python3
"""drive_lane_shares.py DEMO.json...: for each drive demonstration, its steps, how it ended,
the steps spent in each lane (0-2, 0 the right-hand one; the lane nearest the car by the
observation's lateral position, input 20, as `train.lane_shift_min_lane_share` counts them)
and the share of the lane it keeps most, one CSV row per file, highest share first."""
import json, sys

if len(sys.argv) < 2:
    sys.exit(__doc__)
rows = []
for path in sys.argv[1:]:
    d = json.load(open(path))
    road = d.get("scenario") or {}
    width = road.get("lane_width", 3.5)
    half = 1.5 * width  # three lanes
    steps = [0, 0, 0]
    ends = []
    for t in d["trajectories"]:
        for obs in t["observations"][: len(t["actions"])]:
            y = obs[20] * half
            steps[min(range(3), key=lambda k: abs((k - 1) * width - y))] += 1
        ends.append(t.get("end", "?"))
    n = sum(steps)
    lane = max(range(3), key=lambda k: steps[k])
    rows.append((steps[lane] / n, path, n, "+".join(ends), steps, lane))
print("demo,steps,end,lane0,lane1,lane2,main_lane,main_lane_share")
for share, path, n, end, s, lane in sorted(rows, key=lambda r: (-r[0], r[1])):
    print(f"{path},{n},{end},{s[0]},{s[1]},{s[2]},{lane},{share:.3f}")
