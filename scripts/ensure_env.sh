#!/usr/bin/env bash
# Creates (once) the pinned virtual environment and prints its python's path.
# Progress goes to stderr; stdout carries only the path.
# Usage: ensure_env.sh [EXTRA_REQUIREMENTS]   (e.g. bench/requirements.txt: the
# benchmarks' extra packages go into an environment of their own).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
REQ="$ROOT/scripts/requirements.txt"
EXTRA="${1:-}"
HOME_DIR="${LENS_LIGHTS_HOME:-$HOME/.cache/lens-lights}"
KEY="$(cat "$REQ" ${EXTRA:+"$EXTRA"} | sha256sum | cut -c1-12)"
VENV="$HOME_DIR/venv-py3.11-$KEY"

if [ -f "$VENV/.complete" ]; then
  echo "$VENV/bin/python"
  exit 0
fi

# bpy 5.0.1 exists only for CPython 3.11.
find_python() {
  for cand in "${LENS_LIGHTS_PYTHON:-}" python3.11 python3; do
    [ -n "$cand" ] || continue
    if command -v "$cand" >/dev/null 2>&1 &&
       "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      command -v "$cand"; return 0
    fi
  done
  return 1
}

mkdir -p "$HOME_DIR"
exec 9>"$HOME_DIR/.lock-$KEY"
flock 9    # another process may be creating the same environment
if [ ! -f "$VENV/.complete" ]; then
  PYTHON="$(find_python)" || {
    echo "lens-lights: Python 3.11 is needed (bpy==5.0.1 is built for it); set LENS_LIGHTS_PYTHON to one." >&2
    exit 1
  }
  echo "lens-lights: creating the environment in $VENV (once; bpy is about 1 GB) ..." >&2
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV" >&2
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$REQ" \
    ${EXTRA:+-r "$EXTRA"} >&2
  touch "$VENV/.complete"
  echo "lens-lights: environment ready." >&2
fi
echo "$VENV/bin/python"
