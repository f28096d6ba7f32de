"""What this machine is: processors, their theoretical FP32 rates, library versions.

`raybench info` prints it, and every benchmark record carries it. The FP32
rates count one fused multiply-add as two operations, as vendors do:
  CPU: physical cores x clock x float32 SIMD lanes x 2 x FMA units per core
  GPU: multiprocessors x FP32 lanes per multiprocessor x 2 x clock
"""

from __future__ import annotations

import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

# FP32 lanes per multiprocessor by compute capability (CUDA C Programming
# Guide, "Arithmetic Instructions" throughput table).
_FP32_PER_SM = {
    (3, 0): 192,
    (3, 5): 192,
    (3, 7): 192,
    (5, 0): 128,
    (5, 2): 128,
    (5, 3): 128,
    (6, 0): 64,
    (6, 1): 128,
    (6, 2): 128,
    (7, 0): 64,
    (7, 2): 64,
    (7, 5): 64,
    (8, 0): 64,
    (8, 6): 128,
    (8, 7): 128,
    (8, 9): 128,
    (9, 0): 128,
    (10, 0): 128,
    (10, 3): 128,
    (12, 0): 128,
}


def cpu() -> dict:
    import cpuinfo
    import psutil

    info = cpuinfo.get_cpu_info()
    flags = set(info.get("flags", []))
    if "avx512f" in flags:
        simd, bits = "AVX-512", 512
    elif "avx2" in flags or "avx" in flags:
        simd, bits = ("AVX2" if "avx2" in flags else "AVX"), 256
    elif "asimd" in flags or "neon" in flags or platform.machine() in ("arm64", "aarch64"):
        simd, bits = "NEON", 128
    else:
        simd, bits = "SSE", 128
    fma = "fma" in flags or "avx512f" in flags or simd == "NEON"
    # Two FMA pipes per core is the common case on AVX2-era x86 (Intel Haswell
    # on, AMD Zen 2 on) and on Apple/Neoverse cores; it is an assumption, shown.
    fma_units = 2 if fma else 1
    freq = psutil.cpu_freq()
    hz = (
        (freq.max if freq and freq.max else 0) * 1e6
        or info.get("hz_advertised", [0])[0]
        or (freq.current * 1e6 if freq else 0)
    )
    cores = psutil.cpu_count(logical=False) or os.cpu_count() or 1
    lanes = bits // 32
    return {
        "model": info.get("brand_raw") or platform.processor() or "unknown",
        "arch": platform.machine(),
        "physical_cores": cores,
        "logical_cpus": psutil.cpu_count(logical=True) or cores,
        "clock_ghz": round(hz / 1e9, 3),
        "simd": simd,
        "simd_bits": bits,
        "fp32_lanes": lanes,
        "fma_units_per_core": fma_units,
        "fp32_gflops": round(cores * hz / 1e9 * lanes * 2 * fma_units, 1),
        "memory_gib": round(psutil.virtual_memory().total / 2**30, 1),
    }


def gpus() -> list[dict]:
    """The CUDA GPUs numba-cuda can use (none under the simulator or without a driver)."""
    from . import backends

    if not backends.cuda_available():
        return []
    from numba import cuda

    out = []
    driver = _driver_version()
    for gpu in cuda.gpus:
        with gpu:
            d = cuda.get_current_device()
            cc = d.compute_capability
            sms = d.MULTIPROCESSOR_COUNT
            clock_ghz = d.CLOCK_RATE / 1e6
            per_sm = _FP32_PER_SM.get(tuple(cc))
            _free, total = cuda.current_context().get_memory_info()
            name = d.name.decode() if isinstance(d.name, bytes) else d.name
            out.append(
                {
                    "name": name,
                    "compute_capability": f"{cc[0]}.{cc[1]}",
                    "multiprocessors": sms,
                    "clock_ghz": round(clock_ghz, 3),
                    "memory_clock_ghz": round(d.MEMORY_CLOCK_RATE / 1e6, 3),
                    "memory_gib": round(total / 2**30, 1),
                    "fp32_lanes_per_sm": per_sm,
                    "fp32_gflops": round(sms * per_sm * 2 * clock_ghz, 1) if per_sm else None,
                    "driver": driver,
                }
            )
    return out


def wgpu_adapters() -> list[dict]:
    """The adapters wgpu finds (Vulkan, Metal, D3D12, OpenGL), best first:
    name, backend and type (a CPU driver such as lavapipe says "CPU")."""
    from .backends.wgpu.adapters import found

    return [a.describe() for a in found()]


def _driver_version() -> str | None:
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=driver_version", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        return out.stdout.strip().splitlines()[0] if out.returncode == 0 and out.stdout.strip() else None
    except (OSError, subprocess.SubprocessError):
        return None


# The commit a record names, where the checkout's own git metadata cannot be
# trusted: the GPU machine gets a copy of the working tree whose .git is stale,
# so benchmarks/gpu_lease.sh passes the real commit in this variable.
GIT_COMMIT_ENV = "RAYBENCH_GIT_COMMIT"


def git_commit() -> str | None:
    """The commit of the code that runs: $RAYBENCH_GIT_COMMIT where set, else
    `git describe --always --dirty` of the checkout this module is in; None
    outside a checkout (an installed wheel) or without git."""
    given = os.environ.get(GIT_COMMIT_ENV, "").strip()
    if given:
        return given
    try:
        out = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--abbrev=12"],
            capture_output=True,
            text=True,
            timeout=10,
            cwd=Path(__file__).resolve().parent,
        )
        return out.stdout.strip() or None if out.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


def versions() -> dict:
    from . import __version__

    # raybench's own version from the code that runs, which may be a checkout on PYTHONPATH
    out = {"python": platform.python_version(), "raybench": __version__}
    for dist in ("numpy", "numba", "numba-cuda", "llvmlite", "wgpu", "pillow", "click", "rich"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def describe() -> dict:
    return {
        "os": f"{platform.system()} {platform.release()}",
        "cpu": cpu(),
        "gpus": gpus(),
        "wgpu_adapters": wgpu_adapters(),
        "versions": versions(),
    }
