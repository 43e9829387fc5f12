#!/usr/bin/env bash
# Same seed, same numbers across a code change: runs short versions of the
# experiments with two red-cli binaries (e.g. built at the commit before a
# refactoring and after it) and compares their outputs byte for byte apart
# from wall times (scripts/compare-runs.py).
#   bash scripts/same-numbers.sh OLD_BIN NEW_BIN OUT_DIR
# Needs the MuJoCo set-up (bash scripts/setup-mujoco.sh). Exit status 0 when
# every compared file matches. A default changed on purpose is restored for
# the new binary with NEW_DRIVE_ARGS, e.g. across the drive default
# `svg.fixed_std = 0.1` (commit 2a3a0e7):
#   echo '{"svg": {"policy_lr": 3e-5}}' > /tmp/learned-std.json
#   NEW_DRIVE_ARGS="--train-config /tmp/learned-std.json" bash scripts/same-numbers.sh ...
# and a MuJoCo default with NEW_MUJOCO_CONFIG (JSON fields added to the new
# side's --config), e.g. across Hopper RED's clipped reward (session 27):
#   NEW_MUJOCO_CONFIG='{"reward_clips_actions": false}' bash scripts/same-numbers.sh ...
set -euo pipefail
cd "$(dirname "$0")/.."
old=$1; new=$2; out=$3
demo=data/drive-scripted-expert.json
small='{"trpo": {"steps_per_batch": 1024}, "rnd": {"epochs": 20}, "autoencoder": {"epochs": 20}}'
mkdir -p "$out"
echo "$small" > "$out/small.json"
for side in old new; do
  bin=${!side}
  dir="$out/$side"
  extra=""
  side_demo=$demo
  if [ "$side" = new ]; then extra=${NEW_DRIVE_ARGS:-}; fi
  # A binary from before demo format version 2 needs a version 1 file
  # (the same pairs): OLD_DEMO=path/to/old/data/drive-scripted-expert.json.
  if [ "$side" = old ]; then side_demo=${OLD_DEMO:-$demo}; fi
  mkdir -p "$dir"
  cfg="$out/small.json"
  if [ "$side" = new ] && [ -n "${NEW_MUJOCO_CONFIG:-}" ]; then
    cfg="$dir/small.json"
    python3 -c 'import json, sys; a = json.loads(sys.argv[1]); a.update(json.loads(sys.argv[2])); print(json.dumps(a))' \
      "$small" "$NEW_MUJOCO_CONFIG" > "$cfg"
  fi
  # shellcheck disable=SC2086
  "$bin" drive --demo "$side_demo" --steps 3000 --name drive --out-dir "$dir" $extra > "$dir/drive.log" 2>&1
  "$bin" toy --steps 2000 --n 5,10 --seeds 2 --epochs 30 --threads 2 --quiet --runs-dir "$dir" --name toy > "$dir/toy.log" 2>&1
  "$bin" mujoco expert --env hopper --steps 8192 --seed 1 --eval-episodes 2 --config "$out/small.json" --out-dir "$dir" > "$dir/expert.log" 2>&1
  for m in red gail bc; do
    "$bin" mujoco train --env hopper --method $m --steps 4096 --seed 3 --eval-episodes 3 \
      --config "$cfg" --out-dir "$dir" --name hopper-$m --demo "$dir/expert-hopper/demos.json" > "$dir/train-$m.log" 2>&1
  done
done
# eval.json (drive, MuJoCo) is compared too, apart from its wall times; an
# OLD_BIN from before 2026-12 writes a drive eval.json without the unseen
# roads and the demo's road: ONLY=metrics.csv,final.csv,... leaves it out.
only=${ONLY:-metrics.csv,eval.json,final.csv,learned_reward.csv,results.md,policy.json}
python3 scripts/compare-runs.py "$out/old" "$out/new" --only "$only"
