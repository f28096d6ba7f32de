#!/bin/bash
# One mutant's tests: the JIT off (Numba functions run as Python), numba's CUDA
# simulator, a cache folder of its own (stays empty with the JIT off), no .pyc.
export NUMBA_DISABLE_JIT=1 NUMBA_ENABLE_CUDASIM=1 RAYBENCH_CACHE_DIR=/tmp/cr/cache PYTHONDONTWRITEBYTECODE=1
export PYTHONPATH=/tmp/mut-tree/src
cd /tmp/mut-tree || exit 2
exec nice -n 15 /work/main/.venv/bin/python -m pytest -x -q -p no:cacheprovider "@/tmp/cr/sel/$1.txt" "${@:2}"
