#!/usr/bin/env bash
# One-command set-up for hdservo on a Debian machine, idempotent and quiet when
# nothing is missing.  Called by `make setup` (and so by `make test`/`make demo`).
#
#  1. Debian packages: installs only the missing ones, --no-install-recommends,
#     with a dpkg lock timeout, a private TMPDIR and one retry (apt has failed
#     transiently on shared machines, see docs/toolchain notes).
#  2. Python: creates .venv and installs host/ editable with its dev extras;
#     re-runs pip only when host/pyproject.toml changed.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD

# Keep this list the single place that names the project's Debian packages.
PKGS=(
  build-essential gcc make git
  gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi
  qemu-system-arm
  libcmocka-dev
  libsocketcan-dev can-utils
  qemu-system-x86 busybox-static kmod cpio
  python3 python3-venv python3-dev
  clang libclang-rt-14-dev clang-tidy cppcheck
)

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  if [ "$(id -u)" = 0 ]; then
    SUDO=""
  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO="sudo -n"
  else
    echo "setup: missing packages (${missing[*]}) and neither root nor password-less sudo; install them by hand: apt-get install ${missing[*]}" >&2
    exit 1
  fi
  mkdir -p "$ROOT/build/tmp"
  export TMPDIR="$ROOT/build/tmp" DEBIAN_FRONTEND=noninteractive
  APT=($SUDO apt-get install -y -qq --no-install-recommends -o DPkg::Lock::Timeout=600)
  $SUDO apt-get update -qq -o DPkg::Lock::Timeout=600 >/dev/null || $SUDO apt-get update -qq -o DPkg::Lock::Timeout=600 >/dev/null
  if ! "${APT[@]}" "${missing[@]}" >"$ROOT/build/tmp/apt.log" 2>&1; then
    echo "setup: apt-get failed once, retrying (log: build/tmp/apt.log)"
    sleep 2
    "${APT[@]}" "${missing[@]}" >"$ROOT/build/tmp/apt.log" 2>&1 || {
      echo "setup: apt-get install ${missing[*]} failed twice; see build/tmp/apt.log" >&2
      tail -n 20 "$ROOT/build/tmp/apt.log" >&2
      exit 1
    }
  fi
fi

# Python virtual environment with the host package (editable) and dev extras.
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv || {
    echo "setup: '$PY -m venv' failed; install python3-venv" >&2
    exit 1
  }
fi
stamp=.venv/.hdservo-installed
want=$(sha256sum host/pyproject.toml | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing host package into .venv"
  ok=0
  for attempt in 1 2; do
    if .venv/bin/python -m pip install -q --disable-pip-version-check -e "host[dev]"; then
      ok=1; break
    fi
    echo "setup: pip install failed (attempt $attempt)"
  done
  [ $ok = 1 ] || { echo "setup: pip install -e host[dev] failed twice" >&2; exit 1; }
  echo "$want" >"$stamp"
fi
