#!/usr/bin/env bash
# Install brdflab into a virtual environment, .venv, on a fresh Debian machine (root,
# Python ≥ 3.11), with the system libraries that Qt and EGL need.
#   bash scripts/setup.sh          the application            (then: scripts/gui)
#   bash scripts/setup.sh --test   and its test tools (Xvfb, pytest, import-linter, …, and the
#                                  Khronos glTF validator: Node.js from apt, the npm package in .tools/)
#   add --scatmech                 also pySCATMECH (optional; compiles SCATMECH's C++, minutes)
# PYTHON=/path/to/python3 chooses the interpreter (default: python3 on the PATH). A virtual
# environment keeps Debian's own Python untouched (PEP 668 refuses system-wide pip installs).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON="${PYTHON:-python3}"
SYSTEM_PACKAGES=(python3-venv python3-pip libglib2.0-0 libegl1 libgl1 libgl1-mesa-dri libglx-mesa0
  libegl-mesa0 libfontconfig1 libdbus-1-3 libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4
  libxcb-image0 libxcb-keysyms1 libxcb-randr0 libxcb-render-util0 libxcb-shape0 libxcb-xinerama0
  libxcb-xkb1 libxcb-xfixes0 libx11-xcb1 xvfb xauth)
EXTRA_LIST=()
TEST_TOOLS=0
GLTF_VALIDATOR=gltf-validator@2.0.0-dev.3.10  # the Khronos glTF validator (tests/khronos.py runs it)
for arg in "$@"; do
  case "$arg" in
    --test) EXTRA_LIST+=(test); TEST_TOOLS=1 ;;
    --scatmech) SYSTEM_PACKAGES+=(g++ make python3-dev); EXTRA_LIST+=(scatmech) ;;
    *) echo "setup.sh: unknown option $arg (use --test, --scatmech)" >&2; exit 2 ;;
  esac
done
EXTRAS=""
if (( ${#EXTRA_LIST[@]} )); then
  EXTRAS="[$(IFS=,; echo "${EXTRA_LIST[*]}")]"
fi

if (( TEST_TOOLS )) && ! command -v npm >/dev/null 2>&1; then
  SYSTEM_PACKAGES+=(nodejs npm)
fi

if command -v apt-get >/dev/null 2>&1 && [[ $(id -u) -eq 0 ]]; then
  missing=()
  for p in "${SYSTEM_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if (( ${#missing[@]} )); then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
fi

if [[ ! -x .venv/bin/python ]]; then
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip
.venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".${EXTRAS}"
if (( TEST_TOOLS )); then
  npm install --silent --no-audit --no-fund --prefix .tools "$GLTF_VALIDATOR"
fi
echo "brdflab is installed in $(pwd)/.venv: run scripts/gui, or .venv/bin/brdflab --help"
