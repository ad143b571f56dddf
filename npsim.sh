#!/usr/bin/env bash
# NPSim set-up and entry point for a fresh Debian machine (run as root, or with sudo available).
#   bash npsim.sh start   install everything, then open the app on the built-in sample scene
#                         (without a display: run the whole pipeline headless and print where the outputs are)
#   bash npsim.sh test    install everything, then run the test suite under Xvfb
#   bash npsim.sh setup   install only
# Anything after the verb is passed on (e.g. 'bash npsim.sh test -k mesh').
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(pwd)
VENV="$ROOT/.venv"
PY_BIN=${PYTHON:-python3}

APT_PACKAGES=(python3 python3-venv python3-pip xvfb xauth libgl1 libegl1 libgl1-mesa-dri libglib2.0-0
  libxkbcommon-x11-0 libxcb-icccm4 libxcb-keysyms1 libxcb-cursor0 libxcb-image0 libxcb-render-util0
  libxcb-randr0 libxcb-shape0 libxcb-xkb1 libxcb-xinerama0 libdbus-1-3 libfontconfig1 libllvm19)

log() { printf '[npsim.sh] %s\n' "$*" >&2; }

install_system() {
  local missing=()
  for p in "${APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  local SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  log "installing system packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

install_python() {
  local stamp="$VENV/.npsim-installed"
  local want
  want=$(cat pyproject.toml npsim.sh | sha256sum | cut -c1-16)
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$VENV/bin/npsim" ]; then
    return 0
  fi
  [ -x "$VENV/bin/python" ] || { log "creating $VENV"; "$PY_BIN" -m venv "$VENV"; }
  log "installing Python packages into $VENV (first time: a few minutes, ~3 GB)"
  "$VENV/bin/python" -m pip install -q --upgrade pip
  # torch first, pinned: its local CPU build. Anything looser pulls a multi-GB CUDA build.
  "$VENV/bin/python" -m pip install -q "torch==2.13.0"
  "$VENV/bin/python" -m pip install -q -e ".[dev,net]"
  echo "$want" > "$stamp"
}

setup() { install_system; install_python; }

verb=${1:-start}
[ $# -gt 0 ] && shift
case "$verb" in
  setup) setup ;;
  start)
    setup
    exec "$VENV/bin/npsim" start "$@" ;;
  test)
    setup
    # the layers first: core, app and command line keep to their import contracts (pyproject.toml)
    "$VENV/bin/lint-imports" --config pyproject.toml
    # Xvfb: the pyvista 3D view only renders on a real X display (docs/stack.md §3).
    # Two pytest-xdist workers, one test file each at a time, the longest files first and the GUI files on
    # one worker (tests/conftest.py; where the time goes: docs/testing.md);
    # 'bash npsim.sh test -n 0' runs serially.
    exec xvfb-run -a -s "-screen 0 1280x1024x24" "$VENV/bin/python" -m pytest -q -n 2 --dist loadfile "$@" ;;
  *) echo "usage: bash npsim.sh [start|test|setup] [args...]" >&2; exit 2 ;;
esac
