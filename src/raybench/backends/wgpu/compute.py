"""The compute pass on a given wgpu device: pipeline, buffers, the frame texture.

Kept apart from the Tracer so that the viewer can run it on the window's own
device and draw the texture it writes, in the same command buffer, with no
copy (the thesis's pipeline); the Tracer adds the readback for trace().
The BVH is built here too, so that both get the tree of each frame's sphere
count: on the host (raybench.bvh, as for the cpu backend; the default), or
on the GPU (build.py, the LBVH cuda builds too).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ... import bvh as bvh_mod
from ... import layout, lighting
from ...errors import RaybenchError
from ...host import host_available_bytes
from ...kernels.primitives import KINDS
from ...lighting import Shading
from ..limits import HOST_PIXEL_BYTES, check_bvh_fits
from ..options import WgpuOptions
from . import build as gpu_build
from . import shader
from .wavefront import Wavefront

FRAME_FORMAT = "rgba8unorm"
SPHERE_FLOATS = 8  # shader's struct Sphere: the 7 columns and a pad
# triangle.wgsl's struct Facet: the vertices, the colour, the corners' normals
TRIANGLE_FLOATS = gpu_build.SCENE_WORDS["triangle"]
# mixed.wgsl's struct Tagged: a Facet and the tag
MIXED_FLOATS = gpu_build.SCENE_WORDS["mixed"]
UNIFORM_BYTES = 80  # shader's struct Frame: four vec4s, four u32s
# The packet walk's votes are subgroup operations (packet.wgsl). It is no
# default: on the one GPU measured through Vulkan it was slower than a ray at
# a time at every size, where cuda's packets are faster on large trees
# (docs/notes/bvh-walk.md#tried-packets-on-wgpu-kept-as-an-option-not-the-default);
# walk="packet" measures it on another GPU.
PACKET_FEATURE = "subgroup"
RAY_KINDS = len(layout.KINDS)


def check_workgroup(workgroup: tuple[int, int], limits: dict) -> tuple[int, int]:
    """A workgroup (x, y) of positive integers (WgpuOptions), against this adapter's limits."""
    x, y = workgroup
    most = limits["max-compute-invocations-per-workgroup"]
    max_x, max_y = limits["max-compute-workgroup-size-x"], limits["max-compute-workgroup-size-y"]
    if x < 1 or y < 1 or x > max_x or y > max_y or x * y > most:
        raise RaybenchError(
            f"workgroup: this adapter takes sides of 1 to {max_x} x {max_y} and at most {most} "
            f"invocations (x*y), got {x}x{y}"
        )
    return x, y


def check_frame_fits(
    width: int, height: int, spheres: int, workgroup, limits: dict, accel: str = "none", primitive: str = "sphere"
) -> None:
    """The frame, the scene's buffer (spheres: how many primitives of the kind)
    and the tree's largest buffer within this adapter's limits (the device's
    own, as adapters.request_device asked for them), or one line naming the
    limit that is passed."""
    side = limits["max-texture-dimension-2d"]
    if width > side or height > side:
        raise RaybenchError(
            f"size: this adapter's textures are at most {side}x{side}, got {width}x{height}; choose a smaller size"
        )
    groups = limits.get("max-compute-workgroups-per-dimension", 65535)
    if math.ceil(width / workgroup[0]) > groups or math.ceil(height / workgroup[1]) > groups:
        raise RaybenchError(
            f"workgroup: {width}x{height} in workgroups of {workgroup[0]}x{workgroup[1]} needs more "
            f"than this adapter's {groups} workgroups per side; use a larger workgroup"
        )
    binding, buffer = limits["max-storage-buffer-binding-size"], limits["max-buffer-size"]
    largest = min(binding, buffer)
    named = "max-storage-buffer-binding-size" if largest == binding else "max-buffer-size"  # the limit's own name
    noun = KINDS[primitive].NOUN
    needs = [("the hit indices", width * height * 4), (f"the {noun}", spheres * ROW_FLOATS[primitive] * 4)]
    if accel == "bvh":  # at most one node per primitive: with the rows above, the largest of the tree's buffers
        needs.append(("the BVH's nodes", max(spheres, 1) * layout.NODE_BYTES))
    for what, need in needs:
        if need > largest:
            fewer = {"sphere": "fewer spheres", "triangle": "a mesh of fewer triangles"}.get(primitive, f"fewer {noun}")
            raise RaybenchError(
                f"size: {what} need {need / 2**20:.0f} MiB, more than this adapter's largest "
                f"storage buffer ({named}: {largest / 2**20:.0f} MiB); choose a smaller size or {fewer}"
            )


def frame_uniform(basis: np.ndarray, width: int, height: int, count: int) -> bytes:
    rows = np.zeros((4, 4), np.float32)
    rows[:, :3] = basis
    return rows.tobytes() + np.array([width, height, count, 0], np.uint32).tobytes()


def sphere_rows(spheres: np.ndarray) -> np.ndarray:
    """(7, N) columns -> (N, 8) rows, the shader's struct Sphere (one row at least:
    a binding cannot be empty)."""
    rows = np.zeros((max(spheres.shape[1], 1), SPHERE_FLOATS), np.float32)
    rows[: spheres.shape[1], :7] = spheres.T
    return rows


def triangle_rows(triangles: np.ndarray) -> np.ndarray:
    """A mesh's buffer (meshes.mesh_leaves: TRI_SHADED_ROWS or TRI_SMOOTH_ROWS,
    F) -> (F, TRIANGLE_FLOATS) rows, triangle.wgsl's struct Facet: its
    corners' normals zeros where the mesh has none, which surface answers with
    the plane's normal, as the Python does without those rows (one row at
    least: a binding cannot be empty)."""
    rows = np.zeros((max(triangles.shape[1], 1), TRIANGLE_FLOATS), np.float32)
    have = min(triangles.shape[0], TRIANGLE_FLOATS)
    rows[: triangles.shape[1], :have] = triangles[:have].T
    return rows


def mixed_rows(buffer: np.ndarray) -> np.ndarray:
    """A buffer of both kinds (scene_meshes.mixed_leaves: a kind's rows from
    row 0, the tag last) -> (N, MIXED_FLOATS) rows, mixed.wgsl's struct
    Tagged: a triangle's as triangle_rows lays it out; a sphere's centre and
    radius first, its colour moved into the colour's fields (where the
    shading reads either kind's), zeros elsewhere; the tag last (one row at
    least: a binding cannot be empty)."""
    n = buffer.shape[1]
    tag = buffer[buffer.shape[0] - 1]
    rows = np.zeros((max(n, 1), MIXED_FLOATS), np.float32)
    rows[:, :TRIANGLE_FLOATS] = triangle_rows(buffer[: buffer.shape[0] - 1])
    spheres = np.flatnonzero(tag == layout.MIX_SPHERE)
    rows[spheres, : layout.TRI_RED] = 0.0
    rows[spheres, : layout.RADIUS + 1] = buffer[: layout.RADIUS + 1, spheres].T
    rows[spheres, layout.TRI_RED : layout.TRI_BLUE + 1] = buffer[layout.RED : layout.BLUE + 1, spheres].T
    rows[:n, MIXED_FLOATS - 1] = tag
    return rows


# Each kind's scene rows as its WGSL reads them (common.wgsl's `spheres`), and their floats.
SCENE_ROWS = {"sphere": sphere_rows, "triangle": triangle_rows, "mixed": mixed_rows}
ROW_FLOATS = {"sphere": SPHERE_FLOATS, "triangle": TRIANGLE_FLOATS, "mixed": MIXED_FLOATS}


def material_rows(materials: np.ndarray) -> np.ndarray:
    """lighting.materials_array's (5, N) columns -> (N, 5) rows, the shader's
    struct Material (one row at least: a binding cannot be empty)."""
    rows = np.ones((max(materials.shape[1], 1), materials.shape[0]), np.float32)
    rows[: materials.shape[1]] = materials.T
    return rows


def lighting_uniform(shading: Shading) -> bytes:
    """whitted.wgsl's struct Lighting: ambient, background and its gradient
    flag, the sizes (lights, shadow samples, depth), the lights (position and
    radius, colour times intensity), the sample pattern."""
    p = shading.params
    head = np.zeros((2, 4), np.float32)
    head[0, :3] = p[layout.P_AMBIENT : layout.P_AMBIENT + 3]
    head[1, :3] = p[layout.P_BACKGROUND : layout.P_BACKGROUND + 3]
    head[1, 3] = p[layout.P_GRADIENT]
    sizes = np.array([p[layout.P_LIGHTS], p[layout.P_SAMPLES], p[layout.P_DEPTH], 0], np.uint32)
    lights = np.zeros((lighting.MAX_LIGHTS, 2, 4), np.float32)
    n = int(p[layout.P_LIGHTS])
    lights[:n, 0, :3] = shading.lights[layout.LX : layout.LZ + 1, :n].T
    lights[:n, 0, 3] = shading.lights[layout.LRADIUS, :n]
    lights[:n, 1, :3] = shading.lights[layout.LRED : layout.LBLUE + 1, :n].T
    pattern = np.zeros((lighting.MAX_SHADOW_SAMPLES, 4), np.float32)
    pattern[: shading.pattern.shape[1], :3] = shading.pattern.T
    return head.tobytes() + sizes.tobytes() + lights.tobytes() + pattern.tobytes()


class Compute:
    """One scene at one size on one device: encode() records a frame's compute
    pass into a command encoder; texture and hits hold the result. With the
    BVH, build_s is the last build's seconds (the build alone, as on cuda),
    build where it was built ("host" or "gpu", as on cuda), and walk how the
    pass walks it: "ray" (the default) or "packet". primitive: the kind the
    columns of `spheres` are (shader.KIND_PIECES' keys: "sphere",
    "triangle" for meshes.mesh_leaves' buffer, or "mixed" for
    scene_meshes.mixed_leaves')."""

    def __init__(
        self,
        device,
        spheres: np.ndarray,
        width: int,
        height: int,
        options: WgpuOptions,
        shading: Shading | None = None,
        extra_texture_usage: int = 0,
        primitive: str = "sphere",
    ):
        import wgpu

        self.device = device
        self.primitive, self.kind = primitive, KINDS[primitive]
        limits = dict(device.limits)
        self.options = options
        self.accel, self.build, self.walk = options.accel, options.build, options.walk
        # the shader's entry point: the walk's, or Whitted shading's (either accel)
        self.program = "whitted" if shading is not None else (self.walk or "ray")
        self.shading = shading
        self.schedule = options.schedule
        self.wavefront = None  # the wavefront's pipelines and queues (schedule "wavefront")
        if self.walk == "packet" and PACKET_FEATURE not in device.features:
            raise RaybenchError(
                f"walk: the packet walk votes with subgroup operations, and this device has no "
                f"{PACKET_FEATURE!r} feature; use walk='ray'"
            )
        self.workgroup = check_workgroup(options.workgroup, limits)
        self.count = spheres.shape[1]
        check_frame_fits(width, height, self.count, self.workgroup, limits, self.accel, primitive)
        if self.accel == "bvh":
            check_bvh_fits(
                "host",
                self.count,
                host_available_bytes(),
                bvh_mod.BUILD_SPHERE_BYTES,
                width * height * HOST_PIXEL_BYTES,
            )
        self.width, self.height = width, height
        self.uniform = device.create_buffer(
            size=UNIFORM_BYTES, usage=wgpu.BufferUsage.UNIFORM | wgpu.BufferUsage.COPY_DST
        )
        self.spheres = device.create_buffer_with_data(
            data=SCENE_ROWS[primitive](spheres).tobytes(), usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_DST
        )
        self.texture = device.create_texture(
            size=(width, height, 1),
            format=FRAME_FORMAT,
            usage=wgpu.TextureUsage.STORAGE_BINDING | wgpu.TextureUsage.COPY_SRC | extra_texture_usage,
        )
        self.hits = device.create_buffer(
            size=width * height * 4, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC
        )
        if shading is not None:
            self.materials = device.create_buffer_with_data(
                data=material_rows(shading.materials).tobytes(), usage=wgpu.BufferUsage.STORAGE
            )
            self.lighting = device.create_buffer_with_data(
                data=lighting_uniform(shading), usage=wgpu.BufferUsage.UNIFORM
            )
            self.rays = device.create_buffer(
                size=RAY_KINDS * 4,
                usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC | wgpu.BufferUsage.COPY_DST,
            )
        self.pipeline = None
        # kept for rebuilds: a frame of fewer spheres walks a tree of its own
        self.scene_spheres = spheres
        self.tree = None
        self.build_s = None
        self.builder = None  # build "gpu": kept for the next build of as many spheres
        self.kernels = None  # build "gpu": the build's pipelines, compiled once
        if self.accel == "bvh":
            self._build(self.count)
        self.timestamps = "timestamp-query" in device.features
        if self.timestamps:
            self.queries = device.create_query_set(type="timestamp", count=2)
            self.resolved = device.create_buffer(
                size=16, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC
            )
            self.times = device.create_buffer(size=16, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ)
        if self.schedule == "wavefront":
            self.wavefront = Wavefront(self, shading.depth)
        # Waiting for a submission: map a buffer it copies into. (wgpu-py 0.32's
        # queue.on_submitted_work_done_sync fails with a ctypes TypeError.)
        self.fence = device.create_buffer(size=4, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ)

    def compile(self) -> float:
        """Build the pipeline (WGSL to the driver's code); the seconds it took."""
        if self.pipeline is not None:
            return 0.0
        start = time.perf_counter()
        if self.wavefront is not None:
            self.wavefront.compile()
            self.pipeline = self.wavefront  # compiled: its pipelines
            return time.perf_counter() - start
        code = shader.source(self.workgroup, self.accel, self.program, self.primitive)
        module = self.device.create_shader_module(code=code)
        self.pipeline = self.device.create_compute_pipeline(
            layout="auto", compute={"module": module, "entry_point": shader.ENTRY[self.program]}
        )
        self._bind()
        return time.perf_counter() - start

    def _bind(self) -> None:
        """The bind group of the current buffers (a rebuild makes new ones for the tree)."""
        if self.wavefront is not None:
            return  # the wavefront binds its own, at its next frame
        entries = [
            {"binding": 0, "resource": {"buffer": self.uniform}},
            {"binding": 1, "resource": {"buffer": self.spheres}},
            {"binding": 2, "resource": self.texture.create_view()},
            {"binding": 3, "resource": {"buffer": self.hits}},
        ]
        if self.tree is not None:
            entries += [
                {"binding": 4, "resource": {"buffer": self.nodes}},
                {"binding": 5, "resource": {"buffer": self.ordered}},
                {"binding": 6, "resource": {"buffer": self.order}},
            ]
        if self.shading is not None:
            entries += [
                {"binding": 7, "resource": {"buffer": self.materials}},
                {"binding": 8, "resource": {"buffer": self.lighting}},
                {"binding": 9, "resource": {"buffer": self.rays}},
            ]
        self.bind_group = self.device.create_bind_group(layout=self.pipeline.get_bind_group_layout(0), entries=entries)

    def update(self, spheres: np.ndarray) -> str | None:
        """The spheres moved (checked by the Tracer): uploaded over the old
        ones. Their tree follows, as on cuda: with build "gpu" refitted on
        the GPU while its SAH cost stays within options.refit_limit of its fresh
        cost, else rebuilt; with build "host" rebuilt on the host. "refit" or
        "build", or None for brute force."""
        self.device.queue.write_buffer(self.spheres, 0, SCENE_ROWS[self.primitive](spheres).tobytes())
        self.scene_spheres = spheres
        if self.tree is None:
            return None
        refit_s = 0.0
        if self.tree.built_on == "gpu":
            start = time.perf_counter()
            stats = self.builder.run(self.builder.encode_refit)  # after the upload, queued first
            refit_s = time.perf_counter() - start
            if stats.cost <= self.options.refit_limit * self.tree.cost:
                self.build_s = refit_s
                return "refit"
        self._build(self.tree.count)
        self.build_s += refit_s  # the refit that was not enough, then the build
        return "build"

    def _build(self, count: int) -> None:
        """Build the BVH of the first `count` spheres: on the host, uploaded
        (the nodes as the builder wrote them: floats and int32 links in one
        buffer, which the shader's struct Node reads as both), or on the GPU
        from the spheres already there (build.py; the host's tree where the
        GPU's is too deep or there are under two spheres)."""
        spheres = self.scene_spheres[:, :count]
        if self.build == "gpu" and count >= 2:
            if self.builder is None or self.builder.n != count:
                self.kernels = self.kernels or gpu_build.Kernels(self.device, self.primitive)
                self.builder = gpu_build.Builder(
                    self.device, self.spheres, count, quality=self.options.quality, kernels=self.kernels
                )
            tree = gpu_build.build(self.device, spheres, self.builder, primitive=self.kind)
        else:
            tree = gpu_build.upload(self.device, bvh_mod.build(spheres, device="wgpu", primitive=self.kind))
        self.nodes, self.ordered, self.order = tree.nodes, tree.ordered, tree.order
        self.tree, self.build_s = tree, tree.build_s
        if self.pipeline is not None:
            self._bind()

    def encode(self, encoder, basis: np.ndarray, count: int, timed: bool = False) -> None:
        """Record the frame: the camera upload (queued ahead of the command
        buffer) and one dispatch, one invocation per pixel. timed: with
        timestamps around the pass, for read_kernel_ms()."""
        self.compile()
        if self.tree is not None and self.tree.count != count:
            self._build(count)
        self.device.queue.write_buffer(self.uniform, 0, frame_uniform(basis, self.width, self.height, count))
        timed = timed and self.timestamps
        writes = (
            {"query_set": self.queries, "beginning_of_pass_write_index": 0, "end_of_pass_write_index": 1}
            if timed
            else None
        )
        if self.wavefront is not None:
            self.wavefront.encode(encoder, writes)
            if timed:
                encoder.resolve_query_set(self.queries, 0, 2, self.resolved, 0)
                encoder.copy_buffer_to_buffer(self.resolved, 0, self.times, 0, 16)
            return
        if self.shading is not None:
            encoder.clear_buffer(self.rays, 0, RAY_KINDS * 4)
        compute_pass = encoder.begin_compute_pass(timestamp_writes=writes)
        compute_pass.set_pipeline(self.pipeline)
        compute_pass.set_bind_group(0, self.bind_group)
        compute_pass.dispatch_workgroups(
            math.ceil(self.width / self.workgroup[0]), math.ceil(self.height / self.workgroup[1]), 1
        )
        compute_pass.end()
        if timed:
            encoder.resolve_query_set(self.queries, 0, 2, self.resolved, 0)
            encoder.copy_buffer_to_buffer(self.resolved, 0, self.times, 0, 16)

    def encode_fence(self, encoder) -> None:
        """Record a 4-byte copy after the pass, for wait() to wait on."""
        encoder.copy_buffer_to_buffer(self.hits, 0, self.fence, 0, 4)

    def wait(self) -> None:
        """Until the submission that holds encode_fence()'s copy has completed."""
        import wgpu

        self.fence.map_sync(wgpu.MapMode.READ)
        self.fence.unmap()

    def read_kernel_ms(self, period_ns: float) -> float:
        """The pass's GPU time from its timestamps (waits for the submission)."""
        import wgpu

        self.times.map_sync(wgpu.MapMode.READ)
        try:
            begin, end = np.frombuffer(self.times.read_mapped(), np.uint64)
        finally:
            self.times.unmap()
        return float(end - begin) * period_ns / 1e6
