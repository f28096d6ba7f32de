"""Each device's options: what a caller may set, the defaults, and every
check that needs no device, written once.

checked(device, given, shading) turns what a caller gave (render()'s keyword
arguments, the CLI's flags, the viewer's and a cluster task's requests) into
the device's options, a frozen dataclass with its defaults filled in, or
refuses it in one line. A Tracer takes that object and checks only what
needs the device open: an adapter's limits and features, free memory, and
the walk and block that the tree it built chooses where the caller did not.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, fields
from types import SimpleNamespace

import numpy as np

from ..errors import RaybenchError, shown
from ..host import usable_cores
from .limits import is_integer

# --- every device -----------------------------------------------------------------

KERNELS = ("fast", "simple")
# Threads per block the fast CUDA kernel can always launch: its per-thread rays
# take registers, and 256 threads x 255 registers (the most a thread can have)
# fit the 64K registers of every CUDA multiprocessor. 32x32 can fail with
# CUDA_ERROR_LAUNCH_OUT_OF_RESOURCES.
FAST_MAX_THREADS = 256


ACCELS = ("bvh", "none")
# Where a GPU's tree is built (cuda, wgpu): "host" (raybench.bvh's binned SAH
# tree, uploaded) or "gpu" (the LBVH of backends.cuda.build or
# backends.wgpu.build, built where it is walked).
BUILDS = ("host", "gpu")

# The GPU backends' two BVH walks: a ray at a time (kernels.traverse, the
# CPU's code), or a group of pixels' rays as one packet, which visits a node
# if any of its rays enters it (cuda: a block's rays, voting with its
# barriers; wgpu: a subgroup's, voting with subgroup operations). Each backend
# says which it takes by default.
WALKS = ("ray", "packet")
# Whitted's rays over a GPU's threads (_schedule).
SCHEDULES = ("wavefront", "pixel")

# --- cpu ---------------------------------------------------------------------------

MAX_THREADS = 4096
# The cpu's tree by default (tree_width), by kind of primitive and shading: 2,
# the binary SAH tree (bvh.build), every ray walking it alone by the GPUs' own
# walk (kernels/traverse.py); 4, the same tree collapsed into 4-wide nodes
# (bvh.collapse), which the cpu's packets walk (kernels/packets.py), and
# Whitted's other rays alone. Every kind's default is 4 since a mesh's Whitted
# shadow rays go a ray at a time (its SHADOW_PACKETS); until then a mesh's
# Whitted rays walked the binary tree alone: measured both ways
# (docs/triangles.md#the-cpus-walk-packets-for-primary-rays-rays-alone-for-whitteds).
TREE_WIDTH = 4
KIND_TREE_WIDTH = {
    "sphere": {"thesis": TREE_WIDTH, "whitted": TREE_WIDTH},
    "triangle": {"thesis": 4, "whitted": 4},
    "mixed": {"thesis": 4, "whitted": 4},
}
TREE_WIDTHS = (2, 4)

# --- cuda --------------------------------------------------------------------------

# Each kernel's block, as its tuning runs chose it: simple in 16x16 blocks;
# fast (with TRIP) in 8x8 (docs/notes/floors.md#each-version-against-the-floor); the
# BVH walked a ray at a time in 8x8, which also makes a warp a compact 8x4
# patch of pixels whose rays cross much the same nodes (the tuning suite,
# docs/notes/bvh-walk.md#gpu-measured-on-the-h200); the BVH's packets in 8x4
# blocks, one warp, one packet
# (docs/notes/bvh-walk.md#packets-of-rays-on-the-gpu-kept).
DEFAULT_BLOCK = {"simple": (16, 16), "fast": (8, 8), "ray": (8, 8), "packet": (8, 4)}
# The fast kernel's defaults (its options rays and staged): each thread
# traces RAYS_PER_THREAD pixels, one above the other a block height apart, so
# every sphere read from shared memory serves that many tests; spheres are
# staged in shared memory STAGED at a time (16 bytes each).
RAYS_PER_THREAD = 8
MAX_RAYS_PER_THREAD = 16
STAGED = 256
MAX_STAGED = 3071  # 48 KiB of shared memory (with a pad slot), what every CUDA GPU gives a block
# Spheres tested per trip of the cull loop, one branch for all of them: 3
# with 8x8 blocks, as step 5's sweep chose it (4 was no surer a gain, for
# more registers: docs/notes/floors.md#each-version-against-the-floor).
TRIP = 3
MAX_TRIP = 4
MAX_WAVE_GRID = 1 << 24
MAX_TREELET_PASSES = 8

# --- cuda and wgpu -----------------------------------------------------------------

# The default stays the host's SAH tree for scenes that do not move: no tree
# built on the GPU is walked as fast as the host's, and the build is paid
# once, the walk every frame (docs/notes/gpu-build.md#where-it-stands; in WGSL too:
# docs/notes/gpu-build.md#the-same-build-in-wgsl-wgpu).
DEFAULT_BUILD = "host"

# --- wgpu --------------------------------------------------------------------------

# The default workgroups: WebGPU's default limit (256 invocations), so they
# run on every adapter (the thesis's 32x32 runs where the adapter allows
# 1024); for the packet walk 8x8, two NVIDIA warps, each an 8x4 packet of
# pixels, the best of the workgroups tried
# (docs/notes/bvh-walk.md#tried-packets-on-wgpu-kept-as-an-option-not-the-default).
DEFAULT_WORKGROUP = {"none": (16, 16), "ray": (16, 16), "packet": (8, 8)}


def _integer(name: str, value, low: int, high: int) -> int:
    if not is_integer(value) or not low <= value <= high:
        raise RaybenchError(f"{name}: must be an integer from {low} to {high}, got {shown(value)}")
    return int(value)


def _pair(name: str, value) -> tuple[int, int]:
    """Two positive integers (x, y): a block or a workgroup's shape."""
    try:
        x, y = value
    except (TypeError, ValueError):
        raise RaybenchError(f"{name}: must be two integers (x, y), got {shown(value)}") from None
    if not (is_integer(x) and is_integer(y)) or x < 1 or y < 1:
        raise RaybenchError(f"{name}: must be two integers (x, y), each at least 1, got {shown(value)}")
    return int(x), int(y)


def _one_of(name: str, value, choices: tuple) -> str:
    # a str first: an array's `in` compares it element-wise (accepted, or a ValueError from NumPy)
    if not isinstance(value, str) or value not in choices:
        raise RaybenchError(f"{name}: must be one of {', '.join(choices)}, got {shown(value)}")
    return str(value)


def _flag(name: str, value) -> bool:
    """True or False (NumPy's too); None, not given, is False. "no" or 1 is refused, not taken as truthy."""
    if value is None:
        return False
    if not isinstance(value, (bool, np.bool_)):
        raise RaybenchError(f"{name}: must be True or False, got {shown(value)}")
    return bool(value)


def _method(device: str, accel, kernel, brute_only: dict, shading) -> tuple[str, str | None]:
    """(accel, kernel): the acceleration structure and, for brute force, its
    kernel (None with the BVH). accel "bvh" walks a bounding volume
    hierarchy; "none" tests every sphere. brute_only: which options that only
    brute force takes were given; asking for one (or a kernel) without an
    accel means brute force, and with "bvh" it is an error. A Whitted
    frame's brute force is the simple kernel's loop, for every kind of ray."""
    given = ["kernel"] * (kernel is not None) + [name for name, on in brute_only.items() if on]
    if accel is None:
        accel = "none" if given else "bvh"
    _one_of("accel", accel, ACCELS)
    if accel == "bvh":
        if given:
            raise RaybenchError(
                f"{given[0]}: applies to brute force only (accel='none', --accel none), not to the BVH walk"
            )
        return accel, None
    if device == "wgpu":
        if kernel not in (None, "simple"):
            raise RaybenchError(
                f"kernel: the wgpu backend has the simple kernel only (the thesis's loop, one "
                f"invocation per pixel), got {shown(kernel)}; use --kernel simple"
            )
        return accel, "simple"
    if shading is not None:
        refused = ["kernel 'fast'"] * (kernel == "fast") + [name for name, on in brute_only.items() if on]
        if refused:
            raise RaybenchError(
                f"{refused[0]}: applies to the thesis's shading only; Whitted's brute force is the simple kernel"
            )
        return accel, "simple"
    kernel = _one_of("kernel", "fast" if kernel is None else kernel, KERNELS)
    if brute_only.get("constant_count") and kernel != "simple":
        raise RaybenchError("constant_count: applies to the simple kernel only; add kernel='simple' (--kernel simple)")
    return accel, kernel


def _build(build, accel: str) -> str | None:
    """Where a GPU's tree is built: None for brute force, which builds none."""
    if build is None:
        return DEFAULT_BUILD if accel == "bvh" else None
    if accel != "bvh":
        raise RaybenchError("build: applies to the BVH only (accel='bvh'), not to brute force")
    return _one_of("build", build, BUILDS)


def _walk(walk, accel: str, shading) -> str | None:
    """The BVH walk asked for (None: the device chooses; brute force walks none)."""
    if walk is None:
        return None
    if accel != "bvh":
        raise RaybenchError("walk: applies to the BVH walk only (accel='bvh'), not to brute force")
    _one_of("walk", walk, WALKS)
    if shading is not None and walk == "packet":
        raise RaybenchError("walk 'packet': applies to the thesis's shading only; Whitted's rays walk one by one")
    return walk


def _schedule(schedule, shading) -> str | None:
    """How Whitted's rays are spread over a GPU's threads: "wavefront" (the
    default: a bounce's rays of every pixel at once, a stage a kernel;
    kernels/wavefront.py) or "pixel" (a thread traces its pixel's whole tree
    of rays). None for the thesis's shading, whose only rays are primary."""
    if shading is None:
        if schedule is not None:
            raise RaybenchError(f"schedule {shown(schedule)}: applies to Whitted shading only")
        return None
    return "wavefront" if schedule is None else _one_of("schedule", schedule, SCHEDULES)


def _gpu_build(build: str | None, device: str, quality, treelet_passes, refit_limit) -> tuple[str, int, float]:
    """The GPU build's variants (build "gpu" only): quality, where its
    leaves are cut ("sah", as the SAH says; "treelet", also rebuilding
    treelets, treelet_passes times, cuda only; "lbvh", Karras's tree as it
    is); refit_limit, how far a refit may let the tree's SAH cost grow over
    its fresh cost before update() builds anew."""
    from ..bvh import lbvh  # numba comes with it: only once a tracer is made

    for name, value in (("quality", quality), ("treelet_passes", treelet_passes), ("refit_limit", refit_limit)):
        if value is not None and build != "gpu":
            raise RaybenchError(f"{name}: applies to the tree built on the GPU only (build='gpu')")
    qualities = lbvh.QUALITIES if device == "cuda" else tuple(q for q in lbvh.QUALITIES if q != "treelet")
    quality = lbvh.QUALITY if quality is None else _one_of("quality", quality, qualities)
    if treelet_passes is not None and quality != "treelet":
        raise RaybenchError("treelet_passes: applies to quality 'treelet' only")
    passes = (
        lbvh.TREELET_PASSES
        if treelet_passes is None
        else _integer("treelet_passes", treelet_passes, 1, MAX_TREELET_PASSES)
    )
    if refit_limit is None:
        refit_limit = lbvh.REFIT_LIMIT
    elif isinstance(refit_limit, (bool, np.bool_)) or not isinstance(refit_limit, numbers.Real) or not refit_limit >= 0:
        raise RaybenchError(
            f"refit_limit: must be a number of at least 0 (0: always build anew, inf: always refit), "
            f"got {shown(refit_limit)}"
        )
    return quality, passes, float(refit_limit)


def _given(kind, given: dict) -> SimpleNamespace:
    """What a caller gave of kind's options (checked has refused any other
    name), each it left out None: every option's "not given"."""
    return SimpleNamespace(**{**dict.fromkeys(f.name for f in fields(kind)), **given})


@dataclass(frozen=True)
class CpuOptions:
    """The CPU's options. accel: "bvh" or "none"; kernel: brute force's
    ("simple" or "fast"; None with the BVH); constant_count: the simple
    kernel compiled for one sphere count; threads: Numba's threads (default
    every usable core); tree_width: the tree the BVH's rays walk (2: each
    ray alone, as the GPUs do; 4: the cpu's packets; None: the kind of
    primitive's, KIND_TREE_WIDTH)."""

    accel: str
    kernel: str | None
    constant_count: bool
    threads: int
    tree_width: int | None


@dataclass(frozen=True)
class CudaOptions:
    """The cuda backend's options. accel, kernel, constant_count: as the
    CPU's; block: threads per block (x, y), None for the default of the walk
    or kernel (DEFAULT_BLOCK; a walk the tree chooses chooses its block);
    rays, staged, trip: the fast kernel's rays per thread, spheres staged in
    shared memory, and spheres per trip of its cull loop; walk: the BVH's,
    "ray" or "packet", None to let the tree's size choose; build: where the
    tree is built, "host" or "gpu"; quality, treelet_passes, refit_limit:
    the GPU build's leaf cuts, its treelet passes, and how far a refit may
    let the tree's cost grow before update() builds anew; schedule: Whitted's,
    "wavefront" or "pixel"; wave_grid: the wavefront's blocks (None: as many
    as keep every multiprocessor full)."""

    accel: str
    kernel: str | None
    constant_count: bool
    block: tuple[int, int] | None
    rays: int
    staged: int
    trip: int
    walk: str | None
    build: str | None
    quality: str
    treelet_passes: int
    refit_limit: float
    schedule: str | None
    wave_grid: int | None


@dataclass(frozen=True)
class WgpuOptions:
    """The wgpu backend's options. accel, kernel: as the CPU's (brute
    force's one kernel is the simple one); workgroup: invocations per
    workgroup (x, y), None for the walk's default (DEFAULT_WORKGROUP), checked
    against the adapter's limits when it opens; adapter: a name to choose the
    adapter by; walk: "ray" (the default) or "packet"; build, quality,
    refit_limit, schedule: as cuda's (quality "sah" or "lbvh")."""

    accel: str
    kernel: str | None
    workgroup: tuple[int, int]
    adapter: str | None
    walk: str | None
    build: str | None
    quality: str
    refit_limit: float
    schedule: str | None


def _cpu(g: SimpleNamespace, shading=None) -> CpuOptions:
    """The cpu's options from what a caller gave (g, as _given has it), checked."""
    accel, kernel = _method(
        "cpu", g.accel, g.kernel, {"constant_count": _flag("constant_count", g.constant_count)}, shading
    )
    tree_width, threads = g.tree_width, g.threads
    if tree_width is None:
        pass  # the Tracer's kind of primitive chooses (KIND_TREE_WIDTH)
    elif accel != "bvh":
        raise RaybenchError("tree_width: applies to the BVH's packets only (accel='bvh')")
    elif not is_integer(tree_width) or tree_width not in TREE_WIDTHS:
        raise RaybenchError(f"tree_width: must be one of 2, 4, got {shown(tree_width)}")
    threads = usable_cores() if threads is None else _integer("threads", threads, 1, MAX_THREADS)
    return CpuOptions(accel, kernel, bool(g.constant_count), threads, None if tree_width is None else int(tree_width))


def _cuda(g: SimpleNamespace, shading=None) -> CudaOptions:
    """cuda's options from what a caller gave (g, as _given has it), checked."""
    fast_only = {"rays": g.rays is not None, "staged": g.staged is not None, "trip": g.trip is not None}
    accel, kernel = _method(
        "cuda",
        g.accel,
        g.kernel,
        {"constant_count": _flag("constant_count", g.constant_count), **fast_only},
        shading,
    )
    walk = _walk(g.walk, accel, shading)
    build = _build(g.build, accel)
    quality, treelet_passes, refit_limit = _gpu_build(build, "cuda", g.quality, g.treelet_passes, g.refit_limit)
    schedule = _schedule(g.schedule, shading)
    block, wave_grid = g.block, g.wave_grid
    if wave_grid is not None:
        if schedule != "wavefront":
            raise RaybenchError("wave_grid: applies to the wavefront schedule only (Whitted shading)")
        wave_grid = _integer("wave_grid", wave_grid, 1, MAX_WAVE_GRID)
    if block is not None:
        block = _pair("block", block)
        shape = kernel or walk or "ray"
        if block[0] * block[1] > 1024:
            raise RaybenchError(f"block: x*y must be at most 1024 threads, got {block[0]}x{block[1]}")
        if shape != "simple" and block[0] * block[1] > FAST_MAX_THREADS:
            what = "the fast kernel" if shape == "fast" else "the BVH walk"
            need = "its rays need" if shape == "fast" else "its stack and ray need"
            hint = "; use a smaller block or --kernel simple" if shape == "fast" else "; use a smaller block"
            raise RaybenchError(
                f"block: {what} takes at most {FAST_MAX_THREADS} threads per block ({need} the registers), "
                f"got {block[0]}x{block[1]}{hint}"
            )
    rays = _integer("rays", RAYS_PER_THREAD if g.rays is None else g.rays, 1, MAX_RAYS_PER_THREAD)
    return CudaOptions(
        accel, kernel, bool(g.constant_count), block, rays if kernel == "fast" else 1,
        _integer("staged", STAGED if g.staged is None else g.staged, 1, MAX_STAGED),
        _integer("trip", TRIP if g.trip is None else g.trip, 1, MAX_TRIP),
        walk, build, quality, treelet_passes, refit_limit, schedule, wave_grid,
    )  # fmt: skip


def _wgpu(g: SimpleNamespace, shading=None) -> WgpuOptions:
    """wgpu's options from what a caller gave (g, as _given has it), checked."""
    accel, kernel = _method("wgpu", g.accel, g.kernel, {}, shading)
    walk = _walk(g.walk, accel, shading)
    if accel == "bvh":
        walk = walk or "ray"
    workgroup = DEFAULT_WORKGROUP[walk or accel] if g.workgroup is None else _pair("workgroup", g.workgroup)
    adapter = g.adapter
    if adapter is not None and not isinstance(adapter, str):
        raise RaybenchError(f"adapter: must be an adapter's name (text), got {shown(adapter)}")
    build = _build(g.build, accel)
    quality, _, refit_limit = _gpu_build(build, "wgpu", g.quality, None, g.refit_limit)
    return WgpuOptions(
        accel, kernel, workgroup, adapter, walk, build, quality, refit_limit, _schedule(g.schedule, shading)
    )


KINDS = {"cpu": CpuOptions, "cuda": CudaOptions, "wgpu": WgpuOptions}
# Each device's rules, which fill in its record from what a caller gave.
CHECKS = {"cpu": _cpu, "cuda": _cuda, "wgpu": _wgpu}
# What each device takes, by name (render()'s keyword arguments).
NAMES = {device: tuple(f.name for f in fields(kind)) for device, kind in KINDS.items()}


def checked(device: str, given: dict, shading=None):
    """The (resolved) device's options from what a caller gave, or one line
    that names the first thing wrong. shading: the lighting.Shading of a
    Whitted frame (None: the thesis's shading), which some options need."""
    for key in given:
        if key not in NAMES[device]:
            raise RaybenchError(
                f"option {key!r} does not apply to device {device} (its options: {', '.join(NAMES[device])})"
            )
    return CHECKS[device](_given(KINDS[device], given), shading)
