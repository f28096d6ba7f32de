#!/usr/bin/env bash
# Set up .venv (first run) and run the test suite. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")"
if [ ! -x .venv/bin/python ]; then python3 -m venv .venv; fi
.venv/bin/python -m pip install -q --disable-pip-version-check -e '.[test]'
# One test process per core (pytest-xdist), each taking whole files, so that a
# file's fixtures (a Dask cluster, an Xvfb server) start once: most of the
# suite's time is Numba compiling, one core a process.
exec .venv/bin/python -m pytest -n auto --dist loadfile "$@"
