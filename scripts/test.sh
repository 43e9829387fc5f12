#!/usr/bin/env bash
# The whole test suite, from a fresh machine: installs what it needs (the
# MuJoCo 3.17.0 library, Gymnasium's model files and the Gymnasium oracle used
# by the parity tests, all from PyPI), then runs every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup-mujoco.sh
# crates/red-cli/tests/slurm_cli.rs starts a one-node SLURM cluster itself
# (scripts/slurm-local.sh: slurm-wlm and munge from Debian, needs root) and
# stops it at the end unless it was already running.
cargo test --workspace --all-targets --no-fail-fast
# Doc tests (cargo test --all-targets leaves them out).
cargo test --workspace --doc

# The Python package (crates/red-py): pinned build and test tools from PyPI
# into a virtual environment under target/; the extension built by maturin
# in the dev profile, so it reuses the dependencies `cargo test` just built
# (`pip install ./crates/red-py`, the README's command, builds in release);
# then its pytest suite, which compares with the red-cli built above.
PY_ENV=target/red-py-venv
[ -x "$PY_ENV/bin/python" ] || python3 -m venv "$PY_ENV"
"$PY_ENV/bin/pip" install -q maturin==1.16.0 numpy==2.4.6 gymnasium==1.4.0 pytest==9.2.0
PATH="$PWD/$PY_ENV/bin:$PATH" MATURIN_PEP517_ARGS="--profile dev" \
    "$PY_ENV/bin/pip" install -q --no-build-isolation --force-reinstall --no-deps ./crates/red-py
RED_CLI="$PWD/target/debug/red-cli" "$PY_ENV/bin/python" -m pytest -q crates/red-py/tests
