"""The per-pixel program: make the primary ray, find the nearest primitive, shade.

Every backend runs render_pixel for each pixel; they differ only in how pixels
are spread over threads.
"""

import math
from types import SimpleNamespace

import numpy as np

from . import shade, traverse, wavefront, whitted
from .constants import FAR, HALF, ONE, ZERO
from .primitives import sphere


def make(
    jit,
    call=None,
    shadows=None,
    packets_search=None,
    read_row=None,
    words=None,
    primitive=sphere,
    vote=None,
    voted_jit=None,
    positions=False,
):
    """The algorithm compiled with `jit`; a namespace of its functions.
    call: the decorator of Whitted shading's search for a ray's hit (default
    jit), which the CPU compiles as one function called from both of its call
    sites rather than as two inlined copies of the walk (whitted.make).
    shadows: a backend's own way to trace a hit's shadow rays to a light
    (whitted.make's `shadows`, the CPU's packets): then a third Whitted
    program, render_pixel_whitted["packets"], through the tree with them,
    or with each shadow ray alone for a kind whose SHADOW_PACKETS is False.
    packets_search: that program's search for the other rays (the CPU's
    walk of its 4-wide tree, search_tree's signature); default search_tree.
    That program's find is inlined (jit, not call). read_row: how the
    walks read a node's row (traverse.make); words: how they read a leaf's
    primitives from a backend's packed copy (the primitive's make).
    primitive: the kind of primitive the program traces, a module of
    kernels/primitives (its KINDS). vote, voted_jit: traverse.make's, for
    a backend whose rays walk in groups (packet_walk). positions:
    traverse.make's: the tree's walks answer a primitive's column of
    `ordered`, which is then the scene's whole buffer in the tree's order
    and the one the shading reads (the backend gives it as `spheres` with
    the materials in that order too); the hits stored are the original
    indices all the same (original)."""
    call = call or jit
    prim = primitive.make(jit, words)
    shade_hit, shade_miss, to_byte = shade.make(jit)
    kind = primitive.__name__.rsplit(".", 1)[-1]
    walks = traverse.make(jit, prim, read_row, vote, voted_jit, leaf_jit=call, kind=kind, positions=positions)
    nearest_hit_bvh, inverse, walk = walks.nearest_hit_bvh, walks.inverse, walks.walk
    hit_closest, hit_ahead, meets_own, rim, colour = prim.hit, prim.hit_ahead, prim.meets_own, prim.rim, prim.colour
    # the brute-force fast kernels' cull (prepare): a primitive that has one
    # (the sphere's EO and threshold); a triangle has none, and runs the
    # simple kernels alone
    prepare_at = getattr(prim, "prepare_at", None)

    @jit
    def primary_ray(x, y, width, height, basis):
        """Unit direction of the ray through the centre of pixel (x, y), row 0 at
        the top; basis is Camera.basis(): origin, forward, right*plane_w, up*plane_h."""
        fx = np.float32(x)
        fy = np.float32(y)
        u = (fx + HALF) / np.float32(width) - HALF
        v = HALF - (fy + HALF) / np.float32(height)
        dx = basis[1, 0] + basis[2, 0] * u + basis[3, 0] * v
        dy = basis[1, 1] + basis[2, 1] * u + basis[3, 1] * v
        dz = basis[1, 2] + basis[2, 2] * u + basis[3, 2] * v
        inv = ONE / np.float32(math.sqrt(dx * dx + dy * dy + dz * dz))
        return dx * inv, dy * inv, dz * inv

    @jit
    def scan(ox, oy, oz, dx, dy, dz, t_max, any_hit, ahead, own, own_inside, spheres, count):
        """Brute force for any ray, as traverse's walk() takes it through the
        tree: (index of the nearest primitive with 0 < t < t_max, the first
        on a tie, or -1; its t; its hit's datum), over every one in order;
        any_hit stops at the first; ahead, own, own_inside: the secondary
        rays' test (traverse.leaf_test)."""
        closest = t_max
        hit = -1
        hit_d = ZERO
        for i in range(count):
            if ahead:
                if i == own and not meets_own(own_inside):
                    continue
                t, d = hit_ahead(spheres, i, ox, oy, oz, dx, dy, dz, i == own)
            else:
                t, d = hit_closest(spheres, i, ox, oy, oz, dx, dy, dz)
            if t < closest and t > ZERO:
                closest = t
                hit = i
                hit_d = d
                if any_hit:
                    break
        return hit, closest, hit_d

    @jit
    def nearest_hit(ox, oy, oz, dx, dy, dz, spheres, count):
        """Index of the primitive with the smallest t > 0 (the first on a tie,
        -1 if none) and its hit's datum: scan() for the thesis's primary rays."""
        hit, _t, hit_d = scan(ox, oy, oz, dx, dy, dz, FAR, False, False, -1, False, spheres, count)
        return hit, hit_d

    @jit
    def store_pixel(x, y, hit, d, spheres, image, hits):
        """Shade pixel (x, y) from its nearest hit (-1: none) and store it."""
        if hit >= 0:
            red, green, blue = colour(spheres, hit)
            red, green, blue = shade_hit(red, green, blue, rim(spheres, hit), d)
        else:
            red, green, blue = shade_miss(np.float32(x), np.float32(y))
        image[y, x, 0] = to_byte(red)
        image[y, x, 1] = to_byte(green)
        image[y, x, 2] = to_byte(blue)
        hits[y, x] = hit

    @jit
    def original(hit, order):
        """The original index of a hit the tree's walks answered (-1: none)."""
        if positions and hit >= 0:
            return order[np.uint64(hit)]
        return hit

    if positions:

        @jit
        def store_walked(x, y, hit, d, spheres, order, image, hits):
            """store_pixel for a hit a tree's walk answered: its original index stored."""
            store_pixel(x, y, hit, d, spheres, image, hits)
            hits[y, x] = original(hit, order)

    else:

        @jit
        def store_walked(x, y, hit, d, spheres, order, image, hits):
            """store_pixel for a hit a tree's walk answered (its original index)."""
            store_pixel(x, y, hit, d, spheres, image, hits)

    @jit
    def render_pixel(x, y, width, height, basis, spheres, count, image, hits):
        dx, dy, dz = primary_ray(x, y, width, height, basis)
        hit, d = nearest_hit(basis[0, 0], basis[0, 1], basis[0, 2], dx, dy, dz, spheres, count)
        store_pixel(x, y, hit, d, spheres, image, hits)

    @jit
    def render_pixel_bvh(
        x, y, width, height, basis, nodes, links, ordered, order, spheres, image, hits, stack_row, stack_t
    ):
        """render_pixel with the nearest hit found through the BVH: the same pixel."""
        dx, dy, dz = primary_ray(x, y, width, height, basis)
        hit, d = nearest_hit_bvh(
            basis[0, 0], basis[0, 1], basis[0, 2], dx, dy, dz, nodes, links, ordered, order, stack_row, stack_t
        )
        store_pixel(x, y, hit, d, spheres, image, hits)
        if positions:  # a constant of the compile: nothing of it where False
            hits[y, x] = original(hit, order)

    @jit
    def search_tree(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row,
                    stack_t):  # fmt: skip
        """Whitted's rays through the BVH, tree = (nodes, links, ordered, order),
        or a backend's longer tuple that starts with them (the CPU's packets)."""
        nodes, links, ordered, order = tree[0], tree[1], tree[2], tree[3]
        return walk(
            ox, oy, oz, dx, dy, dz, t_max, any_hit, True, own, own_inside, nodes, links, ordered, order, stack_row,
            stack_t,
        )  # fmt: skip

    @jit
    def search_all(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row,
                   stack_t):  # fmt: skip
        """Whitted's rays by brute force, every sphere tested (the tree unused)."""
        return scan(ox, oy, oz, dx, dy, dz, t_max, any_hit, True, own, own_inside, spheres, count)

    def whitted_program(search, shadows=None):
        # the tree's programs answer positions (`positions`); brute force's, original indices
        map_hits = positions and search is not search_all

        if shadows is None:
            stages = whitted.make(jit, call, search, prim, shade_hit, shade_miss, name=f"_{kind}")
            wavefronts[search.__name__] = wavefront.make(jit, stages, primary_ray, shade_hit)
        else:
            # find inlined: with the backend's shadow packets the walk has one call site
            # and is compiled once, and the call's cost goes (measured: docs/notes/whitted.md,
            # "CPU: the primary rays as packets"); a kind whose shadow rays go a ray at a time
            # inlines it at both sites, which compiles longer and runs faster than called
            # (docs/triangles.md)
            stages = whitted.make(jit, jit, search, prim, shade_hit, shade_miss, shadows, name=f"_packets_{kind}")
        whitted_pixel = stages.whitted_pixel

        @jit
        def render_pixel_whitted(x, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree,
                                 stack_row, stack_t, rays_f, rays_i, image, hits):  # fmt: skip
            """render_pixel under Whitted shading (kernels/whitted.py); returns
            the pixel's rays by kind (primary, shadow, reflection, refraction).
            tree: the BVH's (nodes, links, ordered, order), for search_tree.
            stack_row/stack_t: the walk's stack; rays_f/rays_i: the pending
            rays (whitted.RAY_STACK rows), the backend's to give."""
            red, green, blue, hit, primary, shadow, reflection, refraction = whitted_pixel(
                x, y, width, height, basis, primary_ray(x, y, width, height, basis), spheres, count, materials,
                lights, pattern, params, tree, stack_row, stack_t, rays_f, rays_i,
            )  # fmt: skip
            image[y, x, 0] = to_byte(red)
            image[y, x, 1] = to_byte(green)
            image[y, x, 2] = to_byte(blue)
            hits[y, x] = hit
            if map_hits:  # a constant of the compile, as render_pixel_bvh's
                hits[y, x] = original(hit, tree[3])
            return primary, shadow, reflection, refraction

        return render_pixel_whitted

    # Whitted's pixel through the BVH and by brute force, and the wavefront's
    # stages for each (kernels/wavefront.py)
    wavefronts = {}
    render_pixel_whitted = {"bvh": whitted_program(search_tree), "none": whitted_program(search_all)}
    whitted_wavefront = {"bvh": wavefronts["search_tree"], "none": wavefronts["search_all"]}
    if shadows is not None:
        # the kind's choice (its SHADOW_PACKETS): the backend's packets of shadow
        # rays, or each shadow ray through that program's search, as a bounce's is
        own_shadows = shadows if primitive.SHADOW_PACKETS else whitted.per_ray
        render_pixel_whitted["packets"] = whitted_program(packets_search or search_tree, own_shadows)

    prepare = None
    if prepare_at is not None:

        @jit
        def prepare(i, basis, spheres, relative):
            """Fast kernels, once per frame and primitive i: relative[:, i] =
            EO and the cull threshold (the primitive's prepare_at)."""
            ex, ey, ez, s = prepare_at(spheres, i, basis[0, 0], basis[0, 1], basis[0, 2])
            relative[0, i] = ex
            relative[1, i] = ey
            relative[2, i] = ez
            relative[3, i] = s

    return SimpleNamespace(
        render_pixel=render_pixel,
        primary_ray=primary_ray,
        store_pixel=store_pixel,
        original=original,
        store_walked=store_walked,
        prim=prim,
        prepare=prepare,
        render_pixel_bvh=render_pixel_bvh,
        nearest_hit_bvh=nearest_hit_bvh,
        inverse=inverse,
        shade_hit=shade_hit,
        shade_miss=shade_miss,
        to_byte=to_byte,
        nearest_hit=nearest_hit,
        scan=scan,
        render_pixel_whitted=render_pixel_whitted,
        whitted_wavefront=whitted_wavefront,
        walk=walk,
        packet_walk=walks.packet_walk,
    )
