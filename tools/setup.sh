#!/usr/bin/env bash
# Create or reuse the project's venv and install everything the station and its tests need.
# As root it also installs the Debian packages listed in tools/apt-packages.txt; as another user it
# prints the apt-get command to run first (see README, "System packages").
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

mapfile -t APT < <(grep -vE '^\s*(#|$)' tools/apt-packages.txt || true)
if [ "${#APT[@]}" -gt 0 ]; then
  missing=()
  for p in "${APT[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
  if [ "${#missing[@]}" -gt 0 ]; then
    if [ "$(id -u)" = 0 ]; then
      echo "setup: installing Debian packages: ${missing[*]}" >&2
      export DEBIAN_FRONTEND=noninteractive
      apt-get update -qq
      apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
    else
      echo "setup: missing Debian packages (run as root): apt-get install -y ${missing[*]}" >&2
    fi
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup: creating $VENV" >&2
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -c constraints.txt -e '.[dev]'
