"""The harness of the WGSL parity tests (test_wgsl_parity.py,
test_triangle_wgsl.py): a WGSL function run on a CPU adapter once a lane, its
arguments read from one storage buffer and its results written to another,
so that each lane's answer can be held to its Python twin's.

A case is a WGSL body, run by an entry point `parity_NAME` of its own; the
body reads lane i's argument j with arg(j, i) (v3 for three in a row) and
writes its result j with put(j, i, value).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from raybench.backends.wgpu import adapters

F32 = np.float32
LANES = 64  # the parity entry points' workgroup size
# The bindings of the parity entry points: after the tracer's (0 to 13).
IN, OUT = 20, 21
HARNESS = """
@group(0) @binding(IN) var<storage, read> parity_in: array<f32>;
@group(0) @binding(OUT) var<storage, read_write> parity_out: array<f32>;
const PARITY_N: u32 = COUNTu;
fn arg(j: u32, i: u32) -> f32 {
    return parity_in[j * PARITY_N + i];
}
fn put(j: u32, i: u32, value: f32) {
    parity_out[j * PARITY_N + i] = value;
}
fn v3(j: u32, i: u32) -> vec3<f32> {
    return vec3<f32>(arg(j, i), arg(j + 1u, i), arg(j + 2u, i));
}
fn flag(b: bool) -> f32 {
    return select(0.0, 1.0, b);
}
"""
ENTRY = """
@compute @workgroup_size(LANES)
fn parity_NAME(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= PARITY_N) {
        return;
    }
    let k = i32(i);
    BODY
}
"""


def cpu_adapter():
    """A CPU adapter (lavapipe): one that rounds every operation to float32,
    where parity is bit for bit; the test skips without one."""
    cpus = [a for a in adapters.found() if a.type == "CPU"]
    if not cpus:
        pytest.skip(f"no CPU adapter (found: {adapters.listing(adapters.found())}): parity is a CPU adapter's claim")
    return cpus[0]


def entry_points(bodies: dict[str, str], count: int) -> str:
    """The harness for `count` lanes and an entry point parity_NAME for each
    case's body, to follow the WGSL under test."""
    harness = HARNESS.replace("IN", str(IN)).replace("OUT", str(OUT)).replace("COUNT", str(count))
    entries = [
        ENTRY.replace("LANES", str(LANES)).replace("NAME", name).replace("BODY", body) for name, body in bodies.items()
    ]
    return harness + "".join(entries)


def dispatch(device, module, name: str, bound: dict[int, np.ndarray], results: int, n: int) -> np.ndarray:
    """Case `name` run on n lanes, with each array of `bound` in a storage
    buffer at its binding (only those its entry point reads: the automatic
    layout holds no others): its results, (results, n) float32."""
    import wgpu

    storage = wgpu.BufferUsage.STORAGE
    out = device.create_buffer(size=results * n * 4, usage=storage | wgpu.BufferUsage.COPY_SRC)
    entries = [{"binding": OUT, "resource": {"buffer": out}}]
    for binding, rows in bound.items():
        buffer = device.create_buffer_with_data(data=rows.tobytes(), usage=storage)
        entries.append({"binding": binding, "resource": {"buffer": buffer}})
    entry = f"parity_{name}"
    pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": entry})
    group = device.create_bind_group(layout=pipeline.get_bind_group_layout(0), entries=entries)
    encoder = device.create_command_encoder()
    compute_pass = encoder.begin_compute_pass()
    compute_pass.set_pipeline(pipeline)
    compute_pass.set_bind_group(0, group)
    compute_pass.dispatch_workgroups(math.ceil(n / LANES), 1, 1)
    compute_pass.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(out), F32).reshape(results, n)
