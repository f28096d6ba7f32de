#!/usr/bin/env bash
# On the GPU machine (device tool): the kernels against the hardware
# (benchmarks/kernels.py: peaks, simple vs fast, the CUDA fast kernel's shape
# sweep), the fast kernel's PTX, and the thesis suite with both kernels.
# Carries a NumPy 2.4 wheel in .whl (the machine's NumPy 2.5 breaks numba 0.68.0).
# RAYBENCH_GIT_COMMIT is required, as in gpu_lease.sh: the machine's git metadata is stale.
set -uo pipefail
if [ -z "${RAYBENCH_GIT_COMMIT:-}" ]; then
    echo "gpu_kernels.sh: set RAYBENCH_GIT_COMMIT to the commit that runs (git describe --always --dirty --abbrev=12 here)" >&2
    exit 2
fi
export RAYBENCH_GIT_COMMIT
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"
python3 benchmarks/kernels.py --out "$OUT/kernels.jsonl" ${SWEEP:+--sweep} 2>&1 | grep -v '"fast-kernel-shape"' | tee "$OUT/kernels.log"
python3 - "$OUT" <<'PY' | tee -a "$OUT/kernels.log"
import re, sys
import raybench
# compile the fast kernel (brute force's default) through a real frame, then read its PTX; the
# Tracer's own default is the BVH walk
t = raybench.backends.tracer("cuda", raybench.random_spheres(300).spheres, 64, 64, kernel="fast")
t.trace(raybench.Camera().basis(64, 64))
ptx = next(iter(t.kernels()["frame"].inspect_asm().values()))
open(f"{sys.argv[1]}/fast.ptx", "w").write(ptx)
print("fast kernel PTX:", {p: len(re.findall(re.escape(p), ptx)) for p in
      ("ld.local", "st.local", "ld.shared", "ld.global", "fma.rn.f32", "mul.rn.f32", "setp", "bra", "mul.wide")})
PY
if [ -n "${THESIS:-}" ]; then
  timeout -s INT ${THESIS_TIMEOUT:-400} python3 -m raybench bench --no-report --label h100 --out "$OUT" \
    --suite thesis --kernel fast --kernel simple --duration ${DURATION:-2} > "$OUT/bench.log" 2>&1
  tail -3 "$OUT/bench.log"
fi
