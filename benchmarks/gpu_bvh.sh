#!/usr/bin/env bash
# On the GPU machine (device tool), one lease: the BVH and wgpu on the real GPU.
#   1. the machine (nvidia-smi, raybench info: CUDA device and wgpu adapters);
#   2. the BVH, CUDA and fast-kernel tests on the GPU (and wgpu's, where
#      wgpu finds the GPU through the carried Vulkan loader);
#   3. the kernels against the hardware (benchmarks/kernels.py, no sweep);
#   4. the scaling suite on cuda and cpu, then the BVH walk's block shapes.
# Carries .whl (NumPy 2.4: the machine's 2.5 breaks numba 0.68.0; wgpu and
# what it needs) and .gl (the Vulkan and GL loaders, Debian packages).
# Every step has its own time limit, so the whole run ends inside the lease's
# 10 minutes and everything it wrote comes back as one archive in $OUT.
set -uo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
if [ -d .gl ]; then for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/out}; W=/tmp/gpu-bvh; rm -rf "$W"; mkdir -p "$W" "$OUT"
LABEL=${LABEL:-h200}
step() {  # step NAME SECONDS COMMAND...: its output to $W/NAME.log, its time to steps.log
    local name=$1 limit=$2; shift 2
    local t0=$SECONDS
    timeout -s INT "$limit" "$@" > "$W/$name.log" 2>&1
    echo "$name rc=$? $((SECONDS - t0)) s" | tee -a "$W/steps.log"
}
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,memory.total --format=csv > "$W/nvidia-smi.txt" 2>&1
step info 60 python3 -m raybench info
python3 -m raybench info --json > "$W/info.json" 2>/dev/null
if ! grep -qi nvidia "$W/info.log" || ! grep -qi "vulkan" "$W/info.log"; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    step info-vk 60 python3 -m raybench info
fi
step pytest ${PYTEST_S:-150} python3 -m pytest -q -p no:cacheprovider tests/test_bvh.py tests/test_cuda.py \
    tests/test_fast.py tests/test_wgpu.py
step kernels ${KERNELS_S:-80} python3 benchmarks/kernels.py --json "$W/kernels.json" --frames 7
step scaling ${SCALING_S:-170} python3 -m raybench bench --no-report --label "$LABEL" --out "$W/scaling" \
    --suite scaling --device cuda --device cpu --duration ${DURATION:-1}
step tuning ${TUNING_S:-50} python3 -m raybench bench --no-report --label "$LABEL" --out "$W/tuning" \
    --suite tuning --accel bvh --device cuda --duration ${DURATION:-1}
if python3 -c "from raybench import backends; raise SystemExit(not backends.wgpu_gpu_available())" 2>/dev/null; then
    step wgpu ${WGPU_S:-80} python3 -m raybench bench --no-report --label "$LABEL" --out "$W/wgpu" \
        --suite thesis --suite tuning --device wgpu --device cuda --accel none --kernel simple --quick --duration 1
fi
tar -czf "$OUT/gpu-bvh.tar.gz" -C "$W" .
cat "$W/steps.log"; tail -3 "$W/pytest.log"
