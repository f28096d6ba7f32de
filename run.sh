#!/usr/bin/env bash
# Set up .venv (first run) and run the main job: describe this machine, then
# the thesis's benchmark (tests 1 to 7) on every device present, ending with
# where the results and the report are. Extra arguments go to `raybench bench`
# (`./run.sh --quick` for a one-minute smoke run, `--suite all` for everything).
set -euo pipefail
cd "$(dirname "$0")"
if [ ! -x .venv/bin/python ]; then python3 -m venv .venv; fi
.venv/bin/python -m pip install -q --disable-pip-version-check -e .
.venv/bin/raybench info
exec .venv/bin/raybench bench "$@"
