#!/usr/bin/env bash
# Create (or reuse) the Python venv for the Embree test oracle.
#
#   tests/oracle/setup_venv.sh [VENV_DIR]
#
# VENV_DIR defaults to <repo root>/target/pyenv. A relative VENV_DIR given on
# the command line is taken relative to the current directory.
#
# Idempotent: after a successful install the file VENV_DIR/.oracle-requirements.sha256
# holds the sha256 of requirements.txt; while it matches (and the venv's python
# still exists) a rerun does nothing. If requirements.txt changes, the venv is
# deleted and rebuilt from scratch (only if VENV_DIR looks like a venv or is empty).
#
# Environment: PYTHON (default python3) is the interpreter used to create the venv.
set -euo pipefail

die() { echo "setup_venv.sh: error: $*" >&2; exit 1; }

SCRIPT_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO_ROOT="$(cd "$SCRIPT_DIR/../.." && pwd)"
REQ="$SCRIPT_DIR/requirements.txt"
PYTHON="${PYTHON:-python3}"

[ $# -le 1 ] || die "usage: $0 [VENV_DIR]"
VENV="${1:-$REPO_ROOT/target/pyenv}"
[ -n "$VENV" ] || die "empty VENV_DIR"
[ -f "$REQ" ] || die "missing $REQ"

sha256_of() {
    if command -v sha256sum >/dev/null 2>&1; then
        sha256sum "$1" | cut -d' ' -f1
    elif command -v shasum >/dev/null 2>&1; then
        shasum -a 256 "$1" | cut -d' ' -f1
    else
        "$PYTHON" -c 'import hashlib,sys; print(hashlib.sha256(open(sys.argv[1],"rb").read()).hexdigest())' "$1"
    fi
}

WANT="$(sha256_of "$REQ")" || die "cannot hash $REQ"
STAMP="$VENV/.oracle-requirements.sha256"

is_current() {
    [ -f "$STAMP" ] && [ -x "$VENV/bin/python" ] && [ "$(cat "$STAMP" 2>/dev/null)" = "$WANT" ]
}

# Fast path: nothing to do (no python started, no lock taken).
if is_current; then
    exit 0
fi

mkdir -p "$(dirname "$VENV")" || die "cannot create parent directory of $VENV"

# Serialise concurrent runs (e.g. several test processes bootstrapping at once).
if command -v flock >/dev/null 2>&1; then
    exec 9>"$VENV.lock" || die "cannot open lock file $VENV.lock"
    flock 9 || die "cannot lock $VENV.lock"
    # Someone else may have finished the job while we waited.
    if is_current; then
        exit 0
    fi
fi

command -v "$PYTHON" >/dev/null 2>&1 || die "'$PYTHON' not found; install Python >= 3.11 (or set PYTHON=...)"
"$PYTHON" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' \
    || die "$("$PYTHON" -V 2>&1) is too old: the pinned numpy needs Python >= 3.11 (set PYTHON=... to pick another interpreter)"

# Remove a stale/partial venv, but never an arbitrary non-venv directory.
if [ -e "$VENV" ]; then
    if [ -f "$VENV/pyvenv.cfg" ] || [ -z "$(ls -A "$VENV" 2>/dev/null)" ]; then
        echo "setup_venv.sh: (re)building venv at $VENV" >&2
        rm -rf "$VENV" || die "cannot remove stale venv $VENV"
    else
        die "$VENV exists and is not a venv (no pyvenv.cfg); refusing to delete it"
    fi
else
    echo "setup_venv.sh: creating venv at $VENV" >&2
fi

if ! "$PYTHON" -m venv "$VENV"; then
    rm -rf "$VENV"
    die "'$PYTHON -m venv $VENV' failed (on Debian/Ubuntu the python3-venv package provides ensurepip)"
fi

VPY="$VENV/bin/python"
"$VPY" -m pip install --disable-pip-version-check --no-input --quiet \
        --only-binary=:all: -r "$REQ" \
    || die "pip install -r $REQ failed (needs PyPI access and binary wheels for $("$VPY" -V 2>&1) on $(uname -sm))"

# Smoke test: the compiled extension modules load and the versions are the pinned ones.
"$VPY" - "$REQ" <<'PY' || die "installed venv failed its import check"
import sys
from importlib.metadata import version
import numpy
from embreex import rtcore_scene, mesh_construction  # noqa: F401
pins = {}
for line in open(sys.argv[1]):
    line = line.split("#", 1)[0].strip()
    if "==" in line:
        name, ver = line.split("==", 1)
        pins[name.strip()] = ver.strip()
bad = [f"{n}: want {v}, have {version(n)}" for n, v in pins.items() if version(n) != v]
if bad:
    sys.exit("version mismatch: " + "; ".join(bad))
PY

# Stamp last, atomically, so an interrupted run is redone next time.
echo "$WANT" > "$STAMP.tmp" && mv -f "$STAMP.tmp" "$STAMP" || die "cannot write $STAMP"
echo "setup_venv.sh: ready: $VPY" >&2
