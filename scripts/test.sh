#!/usr/bin/env bash
# The whole test suite, from a fresh machine: installs what it needs (the
# MuJoCo 3.17.0 library, Gymnasium's model files and the Gymnasium oracle used
# by the parity tests, all from PyPI), then runs every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup-mujoco.sh
cargo test --workspace --all-targets --no-fail-fast
# Doc tests (cargo test --all-targets leaves them out).
cargo test --workspace --doc
