"""Whitted frames on the cpu through the 4-wide tree (tree_width 4: primary rays as packets, the
other rays as the kind's program sends them) against the binary tree (2: every ray alone), for
one version of raybench (its `src/` first on PYTHONPATH, with its own compile cache): each scene's
two Renderers in turn, 2 threads, two rounds of three frames each, medians of wall time, whether
the two pictures are the same bytes, and a hash of the picture (the same in every version).

    RAYBENCH_CACHE_DIR=/tmp/c-new PYTHONPATH=src python benchmarks/archive/whitted_widths.py \\
        1680x1050 ico81920 ico1310720 "gears 2" "balls 3" "mount 3" meshes.json mixed.json sph10000

Scenes: icoN, the meshes suite's icosphere of N triangles (bench.meshes.mesh_scene); sphN,
random_spheres(N, seed=0, materials=True); NAME.json, the packaged example; else an SPD scene by
its name (bench.scenes). The figures: docs/triangles.md, "Whitted on the cpu: the 4-wide tree,
shadow rays alone".
"""

import hashlib
import statistics
import sys
import time
from importlib import resources

import raybench
from raybench.bench import meshes, scenes


def scene_of(name: str):
    if name.startswith("ico"):
        return meshes.mesh_scene("icosphere", int(name[3:]))
    if name.startswith("sph"):
        return raybench.random_spheres(int(name[3:]), seed=0, materials=True)
    if name.endswith(".json"):
        return raybench.Scene.load(resources.files("raybench.examples") / name)
    return scenes.scene(name)


def main(size: str, names: list[str]) -> None:
    width, height = (int(v) for v in size.split("x"))
    for name in names:
        scene = scene_of(name)
        renderers = {
            w: raybench.Renderer(scene, width, height, device="cpu", threads=2, tree_width=w, shading="whitted")
            for w in (4, 2)
        }
        pictures = {w: r.render(scene.camera) for w, r in renderers.items()}  # compiled, warm
        times = {4: [], 2: []}
        for _ in range(2):
            for w, renderer in renderers.items():
                for _ in range(3):
                    start = time.perf_counter()
                    renderer.render(scene.camera)
                    times[w].append((time.perf_counter() - start) * 1e3)
        same = bool((pictures[4].image == pictures[2].image).all() and (pictures[4].hits == pictures[2].hits).all())
        digest = hashlib.sha1(pictures[4].image.tobytes()).hexdigest()[:12]
        medians = {w: round(statistics.median(t), 1) for w, t in times.items()}
        print(f"{name} {size}: 4-wide {medians[4]} ms, binary {medians[2]} ms, same picture: {same}, {digest}",
              flush=True)  # fmt: skip
        for renderer in renderers.values():
            renderer.close()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
