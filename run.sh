#!/usr/bin/env bash
# Set up .venv (first run) and run the main job: describe this machine, then
# the thesis's benchmark (tests 1 to 7) on every device present, 2 s of frames
# a point (about 4 minutes on a 2-vCPU machine without a GPU), ending with the
# thesis's verdicts, the headline and where the results and the report are.
# `./run.sh --full` is the full run: 10 s a point (`raybench bench`'s default).
# Other arguments go to `raybench bench` (`./run.sh --quick` for a one-minute
# smoke run, `--suite all` for every suite, `--duration S` for S s a point).
set -euo pipefail
cd "$(dirname "$0")"
args=()
duration=(--duration 2)
for arg in "$@"; do
    case "$arg" in
        --full) duration=() ;;
        --quick | --duration | --duration=*) duration=(); args+=("$arg") ;;
        *) args+=("$arg") ;;
    esac
done
quiet=(-q)
if [ ! -x .venv/bin/python ]; then
    echo "setting up .venv: about 640 MiB from PyPI, a minute or two (first run only)"
    python3 -m venv .venv
    quiet=(--progress-bar off)  # a line a package: a first install is never a silent minute in a log
fi
.venv/bin/python -m pip install "${quiet[@]}" --disable-pip-version-check -e .
.venv/bin/raybench info
exec .venv/bin/raybench bench "${duration[@]}" "${args[@]}"
