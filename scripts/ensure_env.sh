#!/usr/bin/env bash
# Creates (once) the pinned virtual environment of one Blender release and prints
# its python's path. Progress and errors go to stderr; stdout carries only the path.
#
# Usage: ensure_env.sh [--blender X.Y] [EXTRA_REQUIREMENTS]
#   --blender X.Y   the release whose pins scripts/envs/blender-X.Y.txt holds
#                   (default: 5.2, the current LTS)
#   EXTRA           more pins in an environment of their own (bench/requirements.txt)
#
# The pins file's first line names the Python it needs ("# python 3.13"). That Python
# is looked for in $LENS_LIGHTS_PYTHON, then pythonX.Y and python3 on the PATH, then
# pyenv's versions, then `uv python find`. Environments live outside the clone under
# ${LENS_LIGHTS_HOME:-~/.cache/lens-lights}, keyed by the pins' hash, so that every
# clone with the same pins reuses them.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DEFAULT_BLENDER="5.2"

BLENDER="$DEFAULT_BLENDER"
if [ "${1:-}" = "--blender" ]; then
  BLENDER="${2:-}"
  shift 2 || true
fi
EXTRA="${1:-}"
REQ="$ROOT/scripts/envs/blender-$BLENDER.txt"
if [ ! -f "$REQ" ]; then
  known="$(cd "$ROOT/scripts/envs" && ls blender-*.txt | sed 's/^blender-//; s/\.txt$//' | tr '\n' ' ')"
  echo "lens-lights: no environment for Blender '$BLENDER'; there are: $known" >&2
  exit 2
fi
PY_VERSION="$(sed -n '1s/^# *python *//p' "$REQ")"
HOME_DIR="${LENS_LIGHTS_HOME:-$HOME/.cache/lens-lights}"
KEY="$(cat "$REQ" ${EXTRA:+"$EXTRA"} | sha256sum | cut -c1-12)"
VENV="$HOME_DIR/venv-blender$BLENDER-py$PY_VERSION-$KEY"

if [ -f "$VENV/.complete" ]; then
  echo "$VENV/bin/python"
  exit 0
fi

is_wanted() {   # is $1 a working python of version $PY_VERSION?
  [ -n "$1" ] && command -v "$1" >/dev/null 2>&1 &&
    "$1" -c "import sys; sys.exit(sys.version_info[:2] != tuple(map(int, '$PY_VERSION'.split('.'))))" 2>/dev/null
}

find_python() {
  local cand
  for cand in "${LENS_LIGHTS_PYTHON:-}" "python$PY_VERSION" python3; do
    if is_wanted "$cand"; then command -v "$cand"; return 0; fi
  done
  for cand in "${PYENV_ROOT:-$HOME/.pyenv}"/versions/"$PY_VERSION"*/bin/python"$PY_VERSION"; do
    if is_wanted "$cand"; then echo "$cand"; return 0; fi
  done
  if command -v uv >/dev/null 2>&1; then
    cand="$(uv python find "$PY_VERSION" 2>/dev/null || true)"
    if is_wanted "$cand"; then echo "$cand"; return 0; fi
  fi
  return 1
}

mkdir -p "$HOME_DIR"
exec 9>"$HOME_DIR/.lock-$KEY"
flock 9    # another process may be creating the same environment
if [ ! -f "$VENV/.complete" ]; then
  PYTHON="$(find_python)" || {
    echo "lens-lights: Blender $BLENDER needs Python $PY_VERSION (its bpy wheels are built for it only) and none was found; install it (\`pyenv install $PY_VERSION\` or \`uv python install $PY_VERSION\`) or set LENS_LIGHTS_PYTHON to one." >&2
    exit 1
  }
  echo "lens-lights: creating the Blender $BLENDER environment in $VENV with $PYTHON (once; bpy is about 1 GB) ..." >&2
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV" >&2
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$REQ" \
    ${EXTRA:+-r "$EXTRA"} >&2
  touch "$VENV/.complete"
  echo "lens-lights: environment ready." >&2
fi
echo "$VENV/bin/python"
