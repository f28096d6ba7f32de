"""A kind's leaf tests inlined or called (compiled.leaf_test), for one version of raybench (its
`src/` first on PYTHONPATH, with a compile cache of its own in RAYBENCH_CACHE_DIR):

    compile  the first Whitted frame of a 320-triangle icosphere through the 4-wide tree, 64x48:
             the process's CPU time, and Numba's compile timers of the slowest functions
    frames   an icosphere's frames through a Renderer at 840x525 on 2 threads (the process's
             CPU time a frame, medians of 5): thesis (the default walk), Whitted through the
             4-wide tree, Whitted with rays alone; the first frame's time too

    RAYBENCH_CACHE_DIR=/tmp/c-old PYTHONPATH=old/src python benchmarks/archive/leaf_calls.py compile
    RAYBENCH_CACHE_DIR=/tmp/c-new PYTHONPATH=src python benchmarks/archive/leaf_calls.py frames 8

The figures: docs/notes/startup.md, "A kind's leaf tests in the packets, called".
"""

import gc
import json
import statistics
import sys
import time

from numba.core.registry import CPUDispatcher

import raybench
from raybench.bench import meshes
from raybench.mesh_render import mesh_scene, recoloured


def icosphere(subdivisions: int):
    """The meshes suite's icosphere at that many subdivisions, framed and coloured as the test's."""
    return recoloured(mesh_scene(meshes.icosphere(20 * 4**subdivisions)), (0.9, 0.6, 0.3))


def compile_times() -> dict:
    scene = icosphere(2)
    start = time.process_time()
    raybench.render(scene, None, 64, 48, device="cpu", shading="whitted", threads=2, tree_width=4)
    timers = []
    for f in (o for o in gc.get_objects() if isinstance(o, CPUDispatcher)):
        for result in f.overloads.values():
            compiled = (result.metadata or {}).get("timers", {}).get("compiler_lock")
            if compiled:
                timers.append((round(compiled, 1), f.py_func.__qualname__))
    return {"first_frame_cpu_s": round(time.process_time() - start, 1), "slowest": sorted(timers)[::-1][:8]}


def frames(subdivisions: int) -> dict:
    scene = icosphere(subdivisions)
    out = {}
    for name, options in (
        ("thesis", {}),
        ("whitted, 4-wide", {"shading": "whitted", "tree_width": 4}),
        ("whitted, rays alone", {"shading": "whitted", "tree_width": 2}),
    ):
        start = time.process_time()
        with raybench.Renderer(scene, 840, 525, device="cpu", threads=2, **options) as renderer:
            renderer.render(scene.camera)
            first = time.process_time() - start
            times = []
            for _ in range(5):
                start = time.process_time()
                renderer.render(scene.camera)
                times.append((time.process_time() - start) * 1e3)
        out[name] = {"first_s": round(first, 1), "frame_ms": round(statistics.median(times), 1)}
    return out


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "compile"
    result = compile_times() if what == "compile" else frames(int(sys.argv[2]) if len(sys.argv) > 2 else 8)
    print(json.dumps({"raybench": raybench.__file__, what: result}))
