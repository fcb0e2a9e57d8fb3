#!/usr/bin/env bash
# Installs everything the project needs on a fresh Debian 12 machine, builds it, and
# (unless --no-demo) runs the main job: simulate a recording, run the C estimator over
# it and write a table and a plot to out/demo/.
#
#   ./scripts/setup.sh            install + build + demo
#   ./scripts/setup.sh --no-demo  install + build only (used by scripts/test.sh)
#
# Idempotent: a second run only checks that everything is there (a few seconds).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
DEMO=1
for arg in "$@"; do
  case "$arg" in
    --no-demo) DEMO=0 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown option '$arg' (see --help)" >&2; exit 2 ;;
  esac
done

log() { printf '[setup] %s\n' "$*"; }

# --- Debian packages ---------------------------------------------------------------
APT_PACKAGES=(
  build-essential cmake ninja-build git pkgconf python3 python3-dev python3-venv python3-pip
  gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm
  libstdc++-arm-none-eabi-newlib
  user-mode-linux kmod iproute2 can-utils
  clang libclang-rt-14-dev lld cppcheck clang-tidy valgrind
)
missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if ((${#missing[@]})); then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  log "installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  log "Debian packages present"
fi

# --- vcan hardware-in-loop backends (docs/hil.md) -----------------------------------------
# QEMU is the HIL's fallback where neither this kernel nor user-mode Linux can run vcan: it
# needs qemu-system-x86 and a static busybox, and boots Debian's linux-image-amd64 kernel,
# fetched with apt-get download and unpacked into the project's cache (~/.cache/attekf, or
# $ATTEKF_CACHE_DIR), not installed on this machine.
HIL_PACKAGES=(qemu-system-x86 busybox-static)
hil_missing=()
for p in "${HIL_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || hil_missing+=("$p")
done
if ((${#hil_missing[@]})); then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  log "installing Debian packages for the HIL's QEMU backend: ${hil_missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${hil_missing[@]}" >/dev/null
fi
hil_kernel="$(python3 "$ROOT/hal/tools/vcan_run.py" --prepare)" \
  || { echo "[setup] cannot fetch the HIL's QEMU guest kernel (above)" >&2; exit 1; }
log "HIL: ${hil_kernel#vcan_run: }"

# --- Python virtual environment -------------------------------------------------------
# The interpreter is the machine's python3 (3.11 here); everything else is pinned.
VENV="$ROOT/.venv"
LOCK="$ROOT/host_tools/requirements.lock"
LOCK_DRONECAN="$ROOT/host_tools/requirements-dronecan.lock"
STAMP="$VENV/.attekf-lock.sha256"
if [ ! -x "$VENV/bin/python" ]; then
  log "creating $VENV"
  python3 -m venv "$VENV"
fi
want="$(sha256sum "$LOCK" "$LOCK_DRONECAN" "$ROOT/host_tools/pyproject.toml" | sha256sum | cut -d' ' -f1)"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$want" ]; then
  log "installing pinned Python packages"
  "$VENV/bin/pip" install -q --disable-pip-version-check -r "$LOCK"
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps --require-hashes -r "$LOCK_DRONECAN"
  # Editable: Python from host_tools/, the C libraries from build/host (built below); the
  # build backend (scikit-build-core) comes pinned from the lock, hence no build isolation.
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$ROOT/host_tools"
  echo "$want" > "$STAMP"
else
  log "Python packages present"
fi

# --- Build (host, the three scalar builds, tests, the Python extension modules) --------
log "configuring and building build/host"
cmake -S "$ROOT" -B "$ROOT/build/host" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DPython3_EXECUTABLE="$VENV/bin/python" >/dev/null
cmake --build "$ROOT/build/host" -j"$(nproc)"

if [ "$DEMO" = 1 ]; then
  "$ROOT/scripts/demo.sh"
fi
