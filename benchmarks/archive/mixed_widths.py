"""A scene of spheres and triangles (the mixed kind) on the cpu through the 4-wide tree
(packets) against the binary tree (rays alone): SPD scenes at 840x525 on 2 threads, the two
widths' Renderers in turn, three rounds of three frames each, medians of wall time, and whether
the pictures are the same bytes.

    python benchmarks/archive/mixed_widths.py thesis "balls 3" "mount 3" "gears 2"
    python benchmarks/archive/mixed_widths.py whitted "balls 3" "mount 3" "gears 2"

The figures: docs/triangles.md, "The cpu's walk".
"""

import statistics
import sys
import time

import raybench
from raybench.bench import scenes


def main(shading: str, names: list[str]) -> None:
    for name in names:
        scene = scenes.scene(name)
        renderers = {
            width: raybench.Renderer(scene, 840, 525, device="cpu", threads=2, tree_width=width, shading=shading)
            for width in (4, 2)
        }
        pictures = {width: r.render(scene.camera) for width, r in renderers.items()}  # compiled, warm
        times = {4: [], 2: []}
        for _ in range(3):
            for width, renderer in renderers.items():
                for _ in range(3):
                    start = time.perf_counter()
                    renderer.render(scene.camera)
                    times[width].append((time.perf_counter() - start) * 1e3)
        same = bool((pictures[4].image == pictures[2].image).all())
        medians = {width: round(statistics.median(t), 1) for width, t in times.items()}
        print(f"{name} ({shading}): packets {medians[4]} ms, rays alone {medians[2]} ms, same picture: {same}")
        for renderer in renderers.values():
            renderer.close()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
