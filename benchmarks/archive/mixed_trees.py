"""Spheres and triangles in one scene: one tree with typed leaves (kernels/primitives/mixed.py)
against one tree per kind (the spheres' tree walked first, then the triangles' with t_max the
first one's hit), on the same primary rays, one thread, the binary tree's walk
(kernels/traverse.py) for both. Side by side in one process, alternating, medians.

    PYTHONPATH=src python benchmarks/archive/mixed_trees.py --repeats 9

Prints one line a scene and design, and checks that both designs find the same nearest hit
on every ray (the same primitive, the same t). docs/notes/mixed-scenes.md has the figures.
"""

import argparse
import statistics
import time

import numba
import numpy as np
import trimesh

import raybench
from raybench import bvh
from raybench.formats import spd
from raybench.kernels import traverse
from raybench.kernels.constants import FAR
from raybench.kernels.primitives import mixed, sphere, triangle
from raybench.layout import STACK, TRI_SHADED_ROWS
from raybench.meshes import Mesh, mesh_leaves
from raybench.scene_meshes import mixed_leaves

_jit = numba.njit(inline="always", fastmath=True)
_one = traverse.make(_jit, mixed.make(_jit)).walk
_spheres = traverse.make(_jit, sphere.make(_jit)).walk
_triangles = traverse.make(_jit, triangle.make(_jit)).walk


def _tree(tree):
    return tree.nodes, tree.links, tree.ordered, tree.order


@numba.njit(nogil=True)
def typed(o, dirs, nodes, links, ordered, order, hits, ts):
    """Every ray through the one tree of typed leaves."""
    stack_row = np.empty(STACK, np.int32)
    stack_t = np.empty(STACK, np.float32)
    for i in range(dirs.shape[0]):
        hit, t, _ = _one(o[0], o[1], o[2], dirs[i, 0], dirs[i, 1], dirs[i, 2], FAR, False, False, -1, False,
                         nodes, links, ordered, order, stack_row, stack_t)  # fmt: skip
        hits[i] = hit
        ts[i] = t


@numba.njit(nogil=True)
def per_kind(o, dirs, s_nodes, s_links, s_ordered, s_order, t_nodes, t_links, t_ordered, t_order, n, hits, ts):
    """Every ray through the spheres' tree, then the triangles' below that hit
    (a triangle's index is n + its own, as the typed buffer numbers it)."""
    stack_row = np.empty(STACK, np.int32)
    stack_t = np.empty(STACK, np.float32)
    for i in range(dirs.shape[0]):
        dx, dy, dz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        hit, t, _ = _spheres(o[0], o[1], o[2], dx, dy, dz, FAR, False, False, -1, False,
                             s_nodes, s_links, s_ordered, s_order, stack_row, stack_t)  # fmt: skip
        t_max = t if hit >= 0 else FAR
        tri, t2, _ = _triangles(o[0], o[1], o[2], dx, dy, dz, t_max, False, False, -1, False,
                                t_nodes, t_links, t_ordered, t_order, stack_row, stack_t)  # fmt: skip
        if tri >= 0:
            hit, t = tri + n, t2
        hits[i] = hit
        ts[i] = t


def primary(camera, width, height):
    """The primary rays' unit directions, (W*H, 3) float32, and the eye."""
    basis = camera.basis(width, height)
    u = ((np.arange(width, dtype=np.float32) + np.float32(0.5)) / np.float32(width) - np.float32(0.5))[None, :]
    v = (np.float32(0.5) - (np.arange(height, dtype=np.float32) + np.float32(0.5)) / np.float32(height))[:, None]
    d = basis[1][None, None, :] + basis[2][None, None, :] * u[..., None] + basis[3][None, None, :] * v[..., None]
    d = d / np.linalg.norm(d, axis=2, keepdims=True)
    return np.ascontiguousarray(basis[0], np.float32), np.ascontiguousarray(d.reshape(-1, 3), np.float32)


def balls_scene(size):
    """The SPD sphereflake: its spheres, and its floor polygon as triangles (NFF.triangles)."""
    nff = spd.balls(size)
    scene, fans = nff.scene(), nff.triangles()
    triangles = np.full((TRI_SHADED_ROWS, len(fans)), 0.8, np.float32)
    triangles[:9] = fans.corners.reshape(len(fans), 9).T
    return scene.spheres, triangles, scene.camera


def icosphere_scene(spheres, subdivisions):
    ico = trimesh.creation.icosphere(subdivisions=subdivisions, radius=3.0)
    mesh = Mesh(np.float32(ico.vertices) + np.float32([0, 0, 12]), np.int32(ico.faces), None)
    scene = raybench.random_spheres(spheres, seed=1)
    return scene.spheres, mesh_leaves(mesh, (0.8, 0.8, 0.8)), scene.camera or raybench.Camera()


def run(name, spheres, triangles, camera, width, height, repeats):
    buffer = mixed_leaves(spheres, triangles)
    one = _tree(bvh.build(buffer, primitive=mixed))
    by_sphere = _tree(bvh.build(spheres, primitive=sphere))
    by_triangle = _tree(bvh.build(triangles, primitive=triangle))
    o, dirs = primary(camera, width, height)
    n = spheres.shape[1]
    hits = [np.empty(len(dirs), np.int64) for _ in range(2)]
    ts = [np.empty(len(dirs), np.float32) for _ in range(2)]
    designs = (
        ("typed leaves", lambda: typed(o, dirs, *one, hits[0], ts[0])),
        ("tree per kind", lambda: per_kind(o, dirs, *by_sphere, *by_triangle, n, hits[1], ts[1])),
    )
    for _, f in designs:
        f()  # compiled
    same = np.array_equal(hits[0], hits[1]) and np.array_equal(ts[0][hits[0] >= 0], ts[1][hits[1] >= 0])
    times = {label: [] for label, _ in designs}
    for r in range(repeats):
        for label, f in designs if r % 2 == 0 else designs[::-1]:
            start = time.perf_counter()
            f()
            times[label].append(time.perf_counter() - start)
    hit_share = float((hits[0] >= 0).mean())
    print(f"{name}: {n:,} spheres, {triangles.shape[1]:,} triangles, {len(dirs):,} rays, "
          f"{hit_share:.0%} hit, same hits: {same}")  # fmt: skip
    medians = {label: statistics.median(v) for label, v in times.items()}
    for label, v in times.items():
        print(f"  {label:14s} median {medians[label] * 1e3:8.1f} ms  {len(dirs) / medians[label] / 1e6:6.2f} M rays/s"
              f"  (p5..p95 {np.percentile(v, 5) * 1e3:.1f}..{np.percentile(v, 95) * 1e3:.1f} ms)")  # fmt: skip
    ratio = medians["tree per kind"] / medians["typed leaves"]
    print(f"  tree per kind / typed leaves: {ratio:.3f}")
    return same


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=400)
    parser.add_argument("--balls", type=int, nargs="+", default=[3, 4], help="the sphereflake's size factors")
    parser.add_argument("--spheres", type=int, nargs="+", default=[1000, 10_000])
    parser.add_argument("--subdivisions", type=int, default=5)
    args = parser.parse_args()
    print(f"numba threads: 1 (one thread a walk); {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    ok = True
    for size in args.balls:
        ok &= run(f"balls {size}", *balls_scene(size), args.width, args.height, args.repeats)
    for n in args.spheres:
        name = f"icosphere {args.subdivisions} + {n} spheres"
        ok &= run(name, *icosphere_scene(n, args.subdivisions), args.width, args.height, args.repeats)
    raise SystemExit(0 if ok else 1)


if __name__ == "__main__":
    main()
