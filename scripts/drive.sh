#!/usr/bin/env bash
# The main job, from a fresh machine: the driving experiment on the
# demonstration shipped in data/. Installs what it needs (the MuJoCo library
# that red-cli links, from PyPI), builds red-cli in release, and runs.
#
# It runs `red-cli drive --demo FILE` with its defaults: RED (RND reward,
# terminal heuristic, SVG(1)-ER after a behaviour-cloning warm start) and BC,
# 5 deterministic evaluation runs each, the paper-style table on stdout and
# runs/drive-main/ with config.json, metrics.csv, eval.json,
# learning_curve.png and eval_paths.png. Extra arguments go to red-cli, e.g.
# `--methods all` for the five methods of the paper's driving table, or
# `--seed 1`. Ctrl-C saves a checkpoint; `red-cli drive --resume
# runs/drive-main` continues it. A second run refuses the folder of the
# first: pass `--force` to move the old one aside (runs/drive-main.old-N).
set -euo pipefail
cd "$(dirname "$0")/.."

DEMO="${DEMO:-data/drive-scripted-expert.json}"
NAME="${NAME:-drive-main}"

bash scripts/setup-mujoco.sh --no-oracle
cargo build --release -p red-cli
# A --name among the arguments wins over NAME (clap takes one --name).
case " $* " in
*" --name "* | *" --name="*) ./target/release/red-cli drive --demo "$DEMO" "$@" ;;
*) ./target/release/red-cli drive --demo "$DEMO" --name "$NAME" "$@" ;;
esac
