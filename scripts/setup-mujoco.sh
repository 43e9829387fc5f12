#!/usr/bin/env bash
# Installs what red-mujoco needs, all from PyPI (no GitHub access needed):
#
#   .mujoco/lib/libmujoco.so.3.17.0   the MuJoCo library that mujoco-rs 7.0.0
#   .mujoco/lib/libmujoco.so          binds, taken from the `mujoco` wheel
#   .mujoco/assets/*.xml              Gymnasium's model files, from the
#                                     `gymnasium` wheel
#   .venv-oracle/                     a virtualenv with gymnasium, mujoco and
#                                     numpy: the oracle of the parity tests
#
# Usage: scripts/setup-mujoco.sh [--no-oracle] [--force]
#   --no-oracle  only the library and the model files (enough to build and
#                run the environments; the parity tests need the oracle)
#   --force      reinstall even what is already present
#
# Idempotent: what is present with the right version is left alone. Needs
# only python3 with pip and venv, and access to PyPI. Any failure stops the
# script with a message and a non-zero exit status.
set -euo pipefail

MUJOCO_VERSION=3.17.0
GYMNASIUM_VERSION=1.4.0

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
LIB_DIR="$ROOT/.mujoco/lib"
ASSETS_DIR="$ROOT/.mujoco/assets"
VENV="$ROOT/.venv-oracle"

oracle=1
force=0
for arg in "$@"; do
    case "$arg" in
        --no-oracle) oracle=0 ;;
        --force) force=1 ;;
        -h | --help)
            sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'
            exit 0
            ;;
        *)
            echo "setup-mujoco.sh: unknown argument '$arg' (try --help)" >&2
            exit 2
            ;;
    esac
done

die() {
    echo "setup-mujoco.sh: ERROR: $*" >&2
    exit 1
}
say() { echo "setup-mujoco.sh: $*"; }

PYTHON="${PYTHON:-python3}"
command -v "$PYTHON" >/dev/null 2>&1 || die "'$PYTHON' not found; install python3 (with pip and venv)"
"$PYTHON" -m pip --version >/dev/null 2>&1 || die "'$PYTHON -m pip' does not work; install pip (Debian: apt-get install python3-pip)"

TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT

# Downloads one wheel of `$1==$2` into $TMP and prints its path.
download_wheel() {
    local name="$1" version="$2" dest="$TMP/$1"
    mkdir -p "$dest"
    "$PYTHON" -m pip download --disable-pip-version-check --quiet --no-deps \
        --only-binary=:all: "$name==$version" -d "$dest" >&2 ||
        die "pip could not download the wheel $name==$version from PyPI"
    local wheel
    wheel="$(find "$dest" -name "*.whl" | head -n 1)"
    [ -n "$wheel" ] || die "no wheel of $name==$version was downloaded"
    echo "$wheel"
}

# Extracts the members of wheel `$1` whose names match the regular expression
# `$2` into folder `$3` (flattened: only the file names are kept), checking
# each against the sha256 that the wheel's RECORD lists.
extract_from_wheel() {
    "$PYTHON" - "$1" "$2" "$3" <<'EOF'
import base64, csv, hashlib, io, os, re, sys, zipfile
wheel, pattern, dest = sys.argv[1], re.compile(sys.argv[2]), sys.argv[3]
with zipfile.ZipFile(wheel) as z:
    record_name = next(n for n in z.namelist() if n.endswith(".dist-info/RECORD"))
    record = {row[0]: row[1] for row in csv.reader(io.TextIOWrapper(z.open(record_name), "utf-8")) if row}
    names = [n for n in z.namelist() if pattern.fullmatch(n)]
    if not names:
        sys.exit(f"nothing in {wheel} matches {pattern.pattern}")
    os.makedirs(dest, exist_ok=True)
    for n in names:
        data = z.read(n)
        algo, _, want = record.get(n, "").partition("=")
        got = base64.urlsafe_b64encode(hashlib.new(algo or "sha256", data).digest()).rstrip(b"=").decode()
        if got != want:
            sys.exit(f"{n}: checksum does not match the wheel's RECORD")
        out = os.path.join(dest, os.path.basename(n))
        with open(out + ".part", "wb") as f:
            f.write(data)
        os.replace(out + ".part", out)
    print(f"extracted {len(names)} file(s) into {dest}")
EOF
}

# --- The MuJoCo library --------------------------------------------------
lib_file="$LIB_DIR/libmujoco.so.$MUJOCO_VERSION"
lib_ok() {
    [ -f "$lib_file" ] && [ -L "$LIB_DIR/libmujoco.so" ] &&
        [ "$(readlink "$LIB_DIR/libmujoco.so")" = "libmujoco.so.$MUJOCO_VERSION" ] &&
        [ "$(cat "$LIB_DIR/VERSION" 2>/dev/null)" = "$MUJOCO_VERSION" ]
}
if [ "$force" = 0 ] && lib_ok; then
    say "MuJoCo $MUJOCO_VERSION library already in $LIB_DIR"
else
    say "fetching MuJoCo $MUJOCO_VERSION from the PyPI wheel"
    wheel="$(download_wheel mujoco "$MUJOCO_VERSION")"
    rm -rf "$LIB_DIR"
    extract_from_wheel "$wheel" "mujoco/libmujoco\.so\.$MUJOCO_VERSION" "$LIB_DIR" ||
        die "could not extract libmujoco.so.$MUJOCO_VERSION from $(basename "$wheel")"
    ln -sf "libmujoco.so.$MUJOCO_VERSION" "$LIB_DIR/libmujoco.so"
    echo "$MUJOCO_VERSION" >"$LIB_DIR/VERSION"
    lib_ok || die "the library in $LIB_DIR is incomplete after extraction"
fi

# --- Gymnasium's model files -----------------------------------------------
MODELS="hopper.xml half_cheetah.xml walker2d_v5.xml ant.xml reacher.xml"
assets_ok() {
    [ "$(cat "$ASSETS_DIR/VERSION" 2>/dev/null)" = "gymnasium $GYMNASIUM_VERSION" ] || return 1
    for m in $MODELS; do [ -f "$ASSETS_DIR/$m" ] || return 1; done
}
if [ "$force" = 0 ] && assets_ok; then
    say "Gymnasium $GYMNASIUM_VERSION model files already in $ASSETS_DIR"
else
    say "fetching Gymnasium $GYMNASIUM_VERSION's model files from the PyPI wheel"
    wheel="$(download_wheel gymnasium "$GYMNASIUM_VERSION")"
    rm -rf "$ASSETS_DIR"
    extract_from_wheel "$wheel" 'gymnasium/envs/mujoco/assets/[^/]+\.xml' "$ASSETS_DIR" ||
        die "could not extract the model files from $(basename "$wheel")"
    echo "gymnasium $GYMNASIUM_VERSION" >"$ASSETS_DIR/VERSION"
    assets_ok || die "a model file ($MODELS) is missing from $ASSETS_DIR after extraction"
fi

# --- The Gymnasium oracle ----------------------------------------------------
oracle_ok() {
    [ -x "$VENV/bin/python" ] && "$VENV/bin/python" - "$MUJOCO_VERSION" "$GYMNASIUM_VERSION" <<'EOF' >/dev/null 2>&1
import sys
import gymnasium, mujoco, numpy
import gymnasium.envs.mujoco.hopper_v5
sys.exit(0 if (mujoco.__version__, gymnasium.__version__) == (sys.argv[1], sys.argv[2]) else 1)
EOF
}
if [ "$oracle" = 1 ]; then
    if [ "$force" = 0 ] && oracle_ok; then
        say "oracle virtualenv already in $VENV"
    else
        say "creating the oracle virtualenv $VENV (gymnasium $GYMNASIUM_VERSION, mujoco $MUJOCO_VERSION, numpy)"
        rm -rf "$VENV"
        "$PYTHON" -m venv "$VENV" ||
            die "'$PYTHON -m venv' failed; install venv support (Debian: apt-get install python3-venv)"
        "$VENV/bin/python" -m pip install --disable-pip-version-check --quiet --only-binary=:all: \
            "mujoco==$MUJOCO_VERSION" "gymnasium[mujoco]==$GYMNASIUM_VERSION" numpy ||
            die "pip could not install the oracle's packages into $VENV"
        oracle_ok || die "the oracle virtualenv $VENV does not import gymnasium $GYMNASIUM_VERSION and mujoco $MUJOCO_VERSION"
    fi
fi

say "done"
