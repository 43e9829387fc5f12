#!/usr/bin/env bash
# The driving experiment over training seeds, then one table across them.
#   bash scripts/drive-seeds.sh DEMO NAME "0 1 2 3 4" [red-cli drive args ...]
# runs `red-cli drive --demo DEMO --seed K --name NAME-sK` for each seed
# (skipping seeds whose eval.json exists, so it can be run again after an
# interruption; an interrupted seed resumes from its checkpoint), two at a
# time, and prints scripts/drive_table.py's table of the finished seeds.
set -euo pipefail
cd "$(dirname "$0")/.."
demo=$1; name=$2; seeds=$3; shift 3
out=${OUT_DIR:-runs}
bin=./target/release/red-cli
[ -x "$bin" ] || cargo build --release -p red-cli
run_seed() {
  local k=$1; shift
  local dir="$out/$name-s$k"
  if [ -f "$dir/eval.json" ]; then return 0; fi
  if [ -f "$dir/checkpoint.json" ]; then
    "$bin" drive --resume "$dir" > "$dir.log" 2>&1
  else
    "$bin" drive --demo "$demo" --seed "$k" --name "$name-s$k" --out-dir "$out" "$@" > "$out/$name-s$k.log" 2>&1
  fi
}
mkdir -p "$out"
jobs=0
for k in $seeds; do
  run_seed "$k" "$@" &
  jobs=$((jobs + 1))
  if [ "$jobs" -ge "${PARALLEL:-2}" ]; then wait -n; jobs=$((jobs - 1)); fi
done
wait
python3 scripts/drive_table.py $(for k in $seeds; do echo "$out/$name-s$k"; done)
