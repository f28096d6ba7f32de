#!/usr/bin/env bash
# What the GPU machine (device tool) runs for the core issue: the test suite on
# the real GPU, the CLI's cuda and cpu renders compared, and a quick timing.
# Carries a NumPy 2.4 wheel in .whl (the machine's NumPy 2.5 breaks numba 0.68.0).
#   RAYBENCH_GIT_COMMIT=<commit> bash benchmarks/archive/gpu_check.sh
# RAYBENCH_GIT_COMMIT is required, as in gpu_lease.sh: the machine's git metadata is stale.
set -uo pipefail
if [ -z "${RAYBENCH_GIT_COMMIT:-}" ]; then
    echo "gpu_check.sh: set RAYBENCH_GIT_COMMIT to the commit that runs (git describe --always --dirty --abbrev=12 here)" >&2
    exit 2
fi
export RAYBENCH_GIT_COMMIT
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,memory.total --format=csv | tee "$OUT/nvidia-smi.txt"
python3 -m raybench info | tee "$OUT/info.txt"
python3 -m raybench info --json > "$OUT/info.json"
python3 -m pytest -q -p no:cacheprovider tests 2>&1 | tee "$OUT/pytest.txt" | tail -15
for d in cuda cpu; do
  /usr/bin/time -f "$d render wall %e s" python3 -m raybench render --spheres 1000 --size 1680x1050 --device $d -o "$OUT/render-$d.png"
done
python3 - "$OUT" <<'PY'
import sys, numpy as np
from PIL import Image
out = sys.argv[1]
a = np.asarray(Image.open(f"{out}/render-cpu.png")).astype(int)
b = np.asarray(Image.open(f"{out}/render-cuda.png")).astype(int)
d = np.abs(a - b).max(axis=2)
print(f"CLI PNGs cpu vs cuda: {a.shape[1]}x{a.shape[0]}, identical pixels {(d == 0).mean():.6%}, "
      f"{(d > 0).sum()} differ, max {d.max()} step(s)")
PY
PYTHONPATH=$PYTHONPATH:$PWD/benchmarks python3 benchmarks/archive/compare_devices.py --spheres 1000 --size 1680x1050 --frames 20 --out "$OUT/compare.jsonl"
