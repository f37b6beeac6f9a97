#!/usr/bin/env bash
# mbdk set-up for a fresh Debian machine, then one job:
#   bash tools/setup.sh report   installs what is missing, builds, runs every study -> report/index.html
#   bash tools/setup.sh test     installs what is missing, builds, runs meson's C/Fortran tests, then pytest
# A second run on a set-up machine skips everything that is done and starts its job within seconds.
set -euo pipefail
cd "$(dirname "$0")/.."
job="${1:-report}"
case "$job" in report|test) ;; *) echo "usage: bash tools/setup.sh report|test" >&2; exit 2 ;; esac

say() { printf '[setup] %s\n' "$*"; }
PY="${PYTHON:-python3}"

# 1. system packages (Debian)
pkgs=(gfortran gcc pkg-config liblapack-dev libopenblas-dev libsundials-dev libsundials-fortran-dev libsuitesparse-dev)
# the tests render the report in a real headless browser (tests/test_report_browser.py)
if [ "$job" = test ]; then pkgs+=(chromium); fi
if ! "$PY" -c 'import venv, ensurepip' 2>/dev/null; then pkgs+=(python3-venv); fi
if ! "$PY" -c 'import sysconfig, os, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  pkgs+=(python3-dev)
fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  if [ "$(id -u)" = 0 ]; then
    say "installing system packages: ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    echo "mbdk needs these Debian packages, which are not installed:" >&2
    echo "  sudo apt-get install --no-install-recommends ${missing[*]}" >&2
    echo "then run this command again." >&2
    exit 1
  fi
else
  say "system packages present"
fi

# 2. virtual environment and Python build/test tools
if [ ! -x .venv/bin/python ]; then
  say "creating .venv"
  "$PY" -m venv .venv
fi
VPY=.venv/bin/python
if ! $VPY -c 'import numpy, mesonbuild, mesonpy, ninja, matplotlib, scipy, sympy, h5py, tqdm, distributed, pytest' 2>/dev/null; then
  say "installing Python tools into .venv"
  $VPY -m pip install -q --upgrade pip
  $VPY -m pip install -q -r tools/requirements.txt
else
  say "Python tools present"
fi

# 3. build and install mbdk (editable: later edits rebuild on import)
builddir="build/$($VPY -c 'import sys; print(f"cp{sys.version_info[0]}{sys.version_info[1]}")')"
if ! $VPY -c 'import mbdk' 2>/dev/null || [ ! -f "$builddir/build.ninja" ]; then
  say "building mbdk (meson-python, editable)"
  $VPY -m pip install -q --no-build-isolation -e . 
else
  say "mbdk installed ($builddir)"
fi

# 4. the job
if [ "$job" = report ]; then
  say "running the studies -> report/index.html"
  exec .venv/bin/mbdk report --out report
else
  say "meson tests (C and Fortran embedding, status table, SUNDIALS link)"
  .venv/bin/meson test -C "$builddir" --print-errorlogs
  say "pytest"
  exec $VPY -m pytest -q tests
fi
