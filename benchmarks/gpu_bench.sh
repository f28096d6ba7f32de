#!/usr/bin/env bash
# On the GPU machine (device tool): run `raybench bench` with the given
# arguments, results under $OUT. Carries a NumPy 2.4 wheel in .whl (the
# machine's NumPy 2.5 breaks numba 0.68.0).
set -uo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
python3 -m raybench bench --no-report --label h100 --out "${OUT:-/tmp/out}" "$@"
