#!/usr/bin/env bash
# Install what brdflab needs on a fresh Debian machine (root, Python ≥ 3.11).
#   bash scripts/setup.sh          the application
#   bash scripts/setup.sh --test   the application and its test tools (Xvfb, pytest, ...)
#   add --scatmech                 also pySCATMECH (optional; compiles SCATMECH's C++, minutes)
set -euo pipefail
cd "$(dirname "$0")/.."

SYSTEM_PACKAGES=(libegl1 libgl1 libgl1-mesa-dri libglx-mesa0 libegl-mesa0 libfontconfig1 libdbus-1-3
  libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1
  libxcb-randr0 libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-xkb1 libxcb-xfixes0 libx11-xcb1)
EXTRA_LIST=()
for arg in "$@"; do
  case "$arg" in
    --test) SYSTEM_PACKAGES+=(xvfb xauth); EXTRA_LIST+=(test) ;;
    --scatmech) SYSTEM_PACKAGES+=(g++ make python3-dev); EXTRA_LIST+=(scatmech) ;;
  esac
done
EXTRAS=""
if (( ${#EXTRA_LIST[@]} )); then
  EXTRAS="[$(IFS=,; echo "${EXTRA_LIST[*]}")]"
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

python3 -m pip install --quiet --disable-pip-version-check -e ".${EXTRAS}"
