#!/usr/bin/env bash
# The main job, from a fresh machine: the driving experiment on the
# demonstration shipped in data/. Installs what it needs (the MuJoCo library
# that red-cli links, from PyPI), builds red-cli in release, and runs.
#
# Today it runs the stages of the driving experiment that exist: it fits
# RED's reward (RND, the release's networks) on the shipped demonstration,
# scores the demonstration under it, and draws the demonstration on its road.
# Learning a policy from that reward (SVG(1)-ER with a behaviour-cloning warm
# start, `red-cli drive --demo FILE`) is not built yet; this script says so
# at the end rather than pretending.
set -euo pipefail
cd "$(dirname "$0")/.."

DEMO="${1:-data/drive-scripted-expert.json}"
OUT="runs/drive-main"

bash scripts/setup-mujoco.sh --no-oracle
cargo build --release -p red-cli
CLI=./target/release/red-cli
mkdir -p "$OUT"

echo "== the demonstration"
"$CLI" demo "$DEMO"
echo "== fitting RED's reward (RND) on it"
"$CLI" support fit --demo "$DEMO" --estimator rnd --out "$OUT/red-rnd.json"
echo "== the demonstration's pairs under that reward"
"$CLI" support score --model "$OUT/red-rnd.json" --demo "$DEMO"
echo "== drawing it"
"$CLI" drive render --demo "$DEMO" --out "$OUT/demo.png"
echo
echo "Wrote $OUT/red-rnd.json and $OUT/demo.png."
echo "Not built yet: learning to drive from this reward (SVG(1)-ER, BC warm start,"
echo "the paper's driving table); see the open issue for 'red-cli drive --demo'."
