#!/usr/bin/env bash
# mbdk set-up for a fresh Debian machine, then one job:
#   bash tools/setup.sh report   installs what is missing, builds, runs every study -> report/index.html
#   bash tools/setup.sh test     installs what is missing, builds, runs meson's C/Fortran tests, then pytest
#   bash tools/setup.sh docs     installs what is missing and the docs extra, builds, then the
#                                documentation (warnings are errors) and its doctests -> docs/_build/html
# A second run on a set-up machine skips everything that is done and starts its job within seconds.
set -euo pipefail
cd "$(dirname "$0")/.."
job="${1:-report}"
case "$job" in report|test|docs) ;; *) echo "usage: bash tools/setup.sh report|test|docs" >&2; exit 2 ;; esac

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
if ! $VPY -c 'import numpy, mesonbuild, mesonpy, ninja, matplotlib, scipy, sympy, h5py, tqdm, distributed, pytest, fmpy' 2>/dev/null; then
  say "installing Python tools into .venv"
  $VPY -m pip install -q --upgrade pip
  $VPY -m pip install -q -r tools/requirements.txt
else
  say "Python tools present"
fi

# the documentation's tools: the docs extra of pyproject.toml, its one list
if [ "$job" = docs ]; then
  if ! $VPY -c 'import sphinx, numpydoc, sphinx_gallery, myst_parser' 2>/dev/null; then
    say "installing the documentation's tools into .venv"
    mapfile -t docs_reqs < <($VPY -c 'import tomllib; print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["docs"]))')
    $VPY -m pip install -q "${docs_reqs[@]}"
  else
    say "documentation tools present"
  fi
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
elif [ "$job" = docs ]; then
  # a fresh environment (-E): the tables and the command line's help the pages read from the
  # package, and every gallery script, are redone on every build
  say "building the documentation -> docs/_build/html (warnings are errors)"
  MPLBACKEND=Agg .venv/bin/sphinx-build -E -W --keep-going -q -b html -d docs/_build/doctrees \
    docs docs/_build/html
  say "running the documentation's snippets as doctests"
  .venv/bin/sphinx-build -W --keep-going -q -b doctest -d docs/_build/doctrees \
    -D plot_gallery=0 docs docs/_build/doctest
  tail -n 5 docs/_build/doctest/output.txt
else
  say "meson tests (C and Fortran embedding, status table, SUNDIALS link)"
  .venv/bin/meson test -C "$builddir" --print-errorlogs
  say "pytest"
  exec $VPY -m pytest -q tests
fi
