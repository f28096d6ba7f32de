#!/bin/bash
# hand.sh MODULE JOB TEST...: apply one recorded mutant to a fresh copy of the
# worktree (/tmp/mut-hand), run the named tests without the JIT, restore.
mod=$1 job=$2; shift 2
rm -rf /tmp/mut-hand && mkdir -p /tmp/mut-hand && git -C /work/wt-mut ls-files -z | (cd /work/wt-mut && xargs -0 tar -c) | tar -x -C /tmp/mut-hand
for f in $(git -C /work/wt-mut ls-files --others --exclude-standard); do mkdir -p /tmp/mut-hand/$(dirname $f); cp /work/wt-mut/$f /tmp/mut-hand/$f; done
sqlite3 /tmp/cr/$mod.sqlite "select diff from work_results where job_id='$job'" | sed 1d | (cd /tmp/mut-hand && patch -p1 -s) || exit 3
cd /tmp/mut-hand
NUMBA_DISABLE_JIT=${JIT_OFF:-1} NUMBA_ENABLE_CUDASIM=1 RAYBENCH_CACHE_DIR=/tmp/cr/cache-hand PYTHONDONTWRITEBYTECODE=1 PYTHONPATH=/tmp/mut-hand/src \
  nice -n 15 /work/main/.venv/bin/python -m pytest -q -p no:cacheprovider "$@" 2>&1 | tail -3
