#!/usr/bin/env bash
# Set up .venv (first run) and run the main job: render 1000 random spheres at
# 1680x1050 on every device present and describe the machine. Extra arguments
# go to `raybench render`.
set -euo pipefail
cd "$(dirname "$0")"
if [ ! -x .venv/bin/python ]; then python3 -m venv .venv; fi
.venv/bin/python -m pip install -q --disable-pip-version-check -e .
.venv/bin/raybench info
.venv/bin/raybench render --spheres 1000 --size 1680x1050 --device cpu -o spheres-cpu.png "$@"
if .venv/bin/python -c 'import sys, raybench.backends as b; sys.exit(not b.cuda_available())'; then
  .venv/bin/raybench render --spheres 1000 --size 1680x1050 --device cuda -o spheres-cuda.png "$@"
fi
