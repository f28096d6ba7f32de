#!/usr/bin/env bash
# On the GPU machine (device tool): run `raybench bench` with the given
# arguments, results under $OUT. Carries a NumPy 2.4 wheel in .whl (the
# machine's NumPy 2.5 breaks numba 0.68.0).
# RAYBENCH_GIT_COMMIT is required, as in gpu_lease.sh: the machine's git metadata is stale.
set -uo pipefail
if [ -z "${RAYBENCH_GIT_COMMIT:-}" ]; then
    echo "gpu_bench.sh: set RAYBENCH_GIT_COMMIT to the commit that runs (git describe --always --dirty --abbrev=12 here)" >&2
    exit 2
fi
export RAYBENCH_GIT_COMMIT
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
python3 -m raybench bench --no-report --label h100 --out "${OUT:-/tmp/out}" "$@"
