"""Where a wgpu frame's time goes between the compute pass and the arrays on
the host: the pass alone (GPU timestamps, and submit-to-done by the wall
clock), then each step of the readback that Tracer.trace() does, timed apart:
the pass that packs the RGB bytes on the GPU and the copies after it
(copy_submit, to done: copy_done), mapping each buffer, and the straight
copies into the (H, W, 3) image and (H, W) hits. The way before, in the same
run: the RGBA texture copied out as it is (rgba_copy_done), then the RGB
channels picked out on the host a plane at a time (rgba_planes). Medians of
--frames warm frames a round. One record of the results schema's "parts"
suite per step and sphere count (quantity "readback-" and the step, e.g.
"readback-copy-done"), options naming the adapter.

    PYTHONPATH=benchmarks python benchmarks/archive/wgpu_readback.py --spheres 1000 --spheres 1000000
"""

import argparse
import sys
import time

import _harness
import numpy as np


def ms(start: float) -> float:
    return (time.perf_counter() - start) * 1e3


def measure(spheres: int, width: int, height: int, frames: int, adapter: str | None) -> dict:
    import wgpu

    from raybench.backends.wgpu.tracer import Tracer
    from raybench.camera import Camera
    from raybench.scene import random_spheres

    scene = random_spheres(spheres, seed=0)
    basis = Camera().basis(width, height)
    steps = {
        k: []
        for k in (
            "kernel",
            "pass_wall",
            "copy_submit",
            "copy_done",
            "map_image",
            "map_hits",
            "image",
            "hits",
            "rgba_copy_done",
            "rgba_planes",
            "trace",
        )
    }
    with Tracer(scene.spheres, width, height, adapter=adapter) as tracer:
        tracer.compile()
        row_bytes = -(-width * 4 // 256) * 256  # a texture-to-buffer copy's rows: WebGPU's alignment
        rgba_read = tracer.device.create_buffer(
            size=row_bytes * height, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        rgba = np.empty(row_bytes * height, np.uint8)
        for _ in range(3):
            tracer.trace(basis)
        for _ in range(frames):
            # the pass alone, waited for through the fence
            encoder = tracer.device.create_command_encoder()
            tracer.compute.encode(encoder, basis, tracer.count, timed=True)
            tracer.compute.encode_fence(encoder)
            start = time.perf_counter()
            tracer.device.queue.submit([encoder.finish()])
            tracer.compute.wait()
            steps["pass_wall"].append(ms(start))
            if tracer.period_ns:
                steps["kernel"].append(tracer.compute.read_kernel_ms(tracer.period_ns))
            # the readback, step by step
            start = time.perf_counter()
            encoder = tracer.device.create_command_encoder()
            tracer.encode_readback(encoder)
            tracer.compute.encode_fence(encoder)
            tracer.device.queue.submit([encoder.finish()])
            steps["copy_submit"].append(ms(start))
            tracer.compute.wait()
            steps["copy_done"].append(ms(start))
            start = time.perf_counter()
            tracer.image_read.map_sync(wgpu.MapMode.READ)
            steps["map_image"].append(ms(start))
            start = time.perf_counter()
            tracer.hits_read.map_sync(wgpu.MapMode.READ)
            steps["map_hits"].append(ms(start))
            start = time.perf_counter()
            tracer.image.reshape(-1)[...] = np.frombuffer(
                tracer.image_read.read_mapped(copy=False), np.uint8, count=tracer.image.size
            )
            steps["image"].append(ms(start))
            start = time.perf_counter()
            tracer.hits[...] = np.frombuffer(tracer.hits_read.read_mapped(copy=False), np.int32).reshape(height, width)
            steps["hits"].append(ms(start))
            tracer.image_read.unmap()
            tracer.hits_read.unmap()
            # the way before: the texture's RGBA rows copied out, the channels picked on the host
            start = time.perf_counter()
            encoder = tracer.device.create_command_encoder()
            encoder.copy_texture_to_buffer(
                {"texture": tracer.compute.texture, "mip_level": 0, "origin": (0, 0, 0)},
                {"buffer": rgba_read, "offset": 0, "bytes_per_row": row_bytes, "rows_per_image": height},
                (width, height, 1),
            )
            tracer.device.queue.submit([encoder.finish()])
            rgba_read.map_sync(wgpu.MapMode.READ)
            steps["rgba_copy_done"].append(ms(start))
            start = time.perf_counter()
            rgba[...] = np.frombuffer(rgba_read.read_mapped(copy=False), np.uint8)
            pixels = rgba.reshape(height, row_bytes // 4, 4)[:, :width]
            for channel in range(3):
                tracer.image[:, :, channel] = pixels[:, :, channel]
            steps["rgba_planes"].append(ms(start))
            del pixels
            rgba_read.unmap()
            # and the whole of trace(), as render() calls it
            start = time.perf_counter()
            tracer.trace(basis)
            steps["trace"].append(ms(start))
        described = tracer.describe()
    return described, {k: v for k, v in steps.items() if v}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, action="append")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--adapter", help="a wgpu adapter by name (default: the best GPU)")
    _harness.add_common(parser, frames=30)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    width, height = (int(v) for v in args.size.split("x"))
    with _harness.Records("wgpu_readback", args, {"adapter": args.adapter}) as out:
        for _ in range(args.rounds):
            for n in args.spheres or [1000, 100_000, 1_000_000]:
                described, steps = measure(n, width, height, args.frames, args.adapter)
                options = {"adapter": str(described.get("name", ""))[:100]}
                for step, times in steps.items():
                    quantity = "readback-" + step.replace("_", "-")
                    out.write(_harness.part(quantity, "wgpu", times, spheres=n, width=width, height=height,
                                            options=options))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
