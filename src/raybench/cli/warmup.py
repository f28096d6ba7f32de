"""raybench warmup: every kernel compiled into the disk cache ahead of the first picture."""

from __future__ import annotations

import click

from ..errors import RaybenchError


@click.command()
@click.option(
    "--device", "devices", multiple=True, help="cpu, cuda or wgpu; repeat for several (default: every device present)"
)
def warmup(devices):
    """Compile every kernel ahead of the first picture, into the disk cache
    (raybench.compiled): the thesis's and Whitted's shading, through the BVH
    and by brute force, and the BVH's builder. Later processes load them."""
    import numpy as np
    from rich.progress import Progress

    from .. import backends, bvh, compiled, lighting
    from ..camera import Camera
    from ..scene import random_spheres

    devices = tuple(dict.fromkeys(devices)) or tuple(backends.present())
    for d in devices:
        if d not in backends.DEVICES:
            raise RaybenchError(f"--device: unknown device {d!r}; choose from {', '.join(backends.DEVICES)}")
        backends.resolve(d)
    scene = random_spheres(8, seed=0, materials=True)
    lit = lighting.Shading.of(scene)
    jobs = [(d, accel, shading) for d in devices for accel in ("bvh", "none") for shading in ("thesis", "whitted")]
    with Progress(transient=True) as progress:
        task = progress.add_task("compiling", total=len(jobs) + 1)
        progress.update(task, description="the BVH's builder, for scenes of every size")
        bvh.compile_builder()
        progress.advance(task)
        for device, accel, shading in jobs:
            progress.update(task, description=f"{device}, {accel}, {shading}")
            options = {"shading": lit} if shading == "whitted" else {}
            with backends.tracer(device, scene.spheres, 4, 4, accel=accel, **options) as tracer:
                tracer.compile()
                tracer.trace(Camera().basis(4, 4))
            progress.advance(task)
    if "cpu" in devices:  # the thesis's brute force on the CPU: both of its kernels
        for kernel in ("fast", "simple"):
            with backends.tracer("cpu", np.zeros((7, 0), np.float32), 4, 4, kernel=kernel) as tracer:
                tracer.compile()
    if "cuda" in devices:  # the tree built on the GPU: its build, its cost and its refit
        with backends.tracer("cuda", scene.spheres, 4, 4, build="gpu") as tracer:
            tracer.update(scene.spheres)
    click.echo(f"compiled for {', '.join(devices)}; the cache: {compiled.CACHE_DIR}")
