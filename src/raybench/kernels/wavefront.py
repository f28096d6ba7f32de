"""Whitted shading by ray, not by pixel: the stages of a wavefront tracer.

The per-pixel program (whitted.py) traces a pixel's whole tree of rays in one
thread, so a GPU warp waits for its busiest pixel. A wavefront instead runs
each bounce of every pixel as one wave, and each wave in stages, each a
kernel over a queue of rays that does one thing:

- extend: the nearest hit of each ray in the wave's queue (the one walk,
  `find`, as the pixel program's);
- shade: at each hit, the light that needs no ray (ambient, or the thesis's
  colour where there are no lights), a shadow ray to each light sample into
  the shadow queue, carrying the light it brings if unblocked, and the
  hit's children (reflection, refraction) into the next wave's queue; a ray
  that met nothing brings the background;
- shadow: any hit along each shadow ray, stopping at the first blocker; an
  unblocked one brings its light.

Every formula is whitted.py's (its namespace: surface, shows, toward, glint,
branches, background), and a child is cast or dropped by the same rule
(prune, from the ray's own slack), so the wavefront casts the pixel
program's rays, no more and no fewer. Only the order in which a pixel's
light is summed differs: a wave adds it from many threads at once, so it is
added as integers (fixed point, units of 1 / FIXED), which sum to the same
total in any order: a frame is the same on every run.

The queues are structures of arrays, a column a ray:
- rays: float32 RAY_ROWS (origin, direction, weight rgb, slack) and int32
  RAY_IDS (pixel, depth, kind, the sphere it leaves, whether it goes in);
- shadow rays: float32 SHADOW_ROWS (origin, direction, length, the light it
  brings) and int32 SHADOW_IDS (pixel, the sphere it leaves, inside).
A backend decides how slots in the queues are claimed and how the stages
are launched; these functions are what runs for one ray.
"""

from types import SimpleNamespace

import numpy as np

from ..layout import (
    IOR,
    P_AMBIENT,
    P_LIGHTS,
    PRIMARY,
    REFLECT,
    REFLECTION,
    REFRACTION,
    SHININESS,
    SPECULAR,
    TRANSMIT,
)
from .constants import FAR, ONE, TWO, ZERO
from .whitted import CUTOFF, OFFSET

RAY_ROWS = 10
RAY_IDS = 5
R_PIXEL, R_DEPTH, R_KIND, R_OWN, R_INSIDE = range(RAY_IDS)
SHADOW_ROWS = 10
SHADOW_IDS = 3
# A pixel's light summed as integers in units of 1 / FIXED. Each
# contribution is clamped to [-CLAMP, CLAMP] first: a pixel's weights add up
# to at most 1 and a colour is at least -1 (the thesis's rim), so a
# contribution above 2 makes the pixel white whatever else it gets, and the
# clamp cannot change a byte; 2**17 rays of a pixel at most stay far inside
# int64.
FIXED = np.float32(2.0**30)
CLAMP = np.float32(4.0)


def make(jit, whitted, primary_ray, shade_hit):
    """The stages over whitted.make's namespace for one search (the tree's
    or brute force's); primary_ray and shade_hit: trace.py's."""
    find = whitted.find
    surface = whitted.surface
    rim = whitted.rim
    colour = whitted.colour
    shows = whitted.shows
    toward = whitted.toward
    lifted = whitted.lifted
    glint = whitted.glint
    branches = whitted.branches
    light_samples = whitted.light_samples
    background = whitted.background

    @jit
    def fixed(c):
        """A contribution in fixed point (the module's docstring)."""
        return np.int64(min(max(c, -CLAMP), CLAMP) * FIXED)

    @jit
    def resolve(total):
        """A pixel's summed light, back as a float."""
        return np.float32(np.float64(total) / np.float64(FIXED))

    @jit
    def put(queue, k, values):
        """A record's values (a tuple of one type) into column k of a
        queue's array, one row each: the queues are structures of arrays."""
        for row in range(len(values)):
            queue[row, k] = values[row]

    @jit
    def put_ray(rays_f, rays_i, slot, ox, oy, oz, dx, dy, dz, wr, wg, wb, slack, pixel, depth, kind, own, inside):
        put(rays_f, slot, (ox, oy, oz, dx, dy, dz, wr, wg, wb, slack))
        rays_i[R_PIXEL, slot] = pixel
        rays_i[R_DEPTH, slot] = depth
        rays_i[R_KIND, slot] = kind
        rays_i[R_OWN, slot] = own
        rays_i[R_INSIDE, slot] = inside

    @jit
    def emit_primary(rays_f, rays_i, slot, pixel, width, height, basis):
        """The primary ray of a pixel (y * width + x) into the queue."""
        x = pixel % width
        y = pixel // width
        dx, dy, dz = primary_ray(x, y, width, height, basis)
        put_ray(rays_f, rays_i, slot, basis[0, 0], basis[0, 1], basis[0, 2], dx, dy, dz, ONE, ONE, ONE, CUTOFF,
                pixel, 0, PRIMARY, -1, 0)  # fmt: skip

    @jit
    def extend(rays_f, rays_i, slot, spheres, count, tree, stack_row, stack_t):
        """The nearest hit of the ray at slot: (sphere or -1, t, half-chord)."""
        return find(
            rays_f[0, slot], rays_f[1, slot], rays_f[2, slot], rays_f[3, slot], rays_f[4, slot], rays_f[5, slot],
            FAR, False, rays_i[R_OWN, slot], rays_i[R_INSIDE, slot] != 0, spheres, count, tree, stack_row, stack_t,
        )  # fmt: skip

    @jit
    def unblocked(shadows_f, shadows_i, slot, spheres, count, tree, stack_row, stack_t):
        """Whether the shadow ray at slot reaches its light."""
        blocker, _t, _d = find(
            shadows_f[0, slot], shadows_f[1, slot], shadows_f[2, slot], shadows_f[3, slot], shadows_f[4, slot],
            shadows_f[5, slot], shadows_f[6, slot], True, shadows_i[1, slot], shadows_i[2, slot] != 0, spheres,
            count, tree, stack_row, stack_t,
        )  # fmt: skip
        return blocker < 0

    @jit
    def missed(rays_f, rays_i, slot, width, params):
        """The light a ray that met nothing brings: its weight times the
        background its pixel sees."""
        pixel = rays_i[R_PIXEL, slot]
        br, bg, bb = background(np.float32(pixel % width), np.float32(pixel // width), params)
        return rays_f[6, slot] * br, rays_f[7, slot] * bg, rays_f[8, slot] * bb

    @jit
    def shade(rays_f, rays_i, slot, i, t, d, max_depth, spheres, materials, lights, pattern, params):
        """The hit of the ray at slot on sphere i (t, half-chord d): what it
        brings now, the shadow rays it casts and its children, before any
        slot is claimed for them. Returns (the light that needs no ray, rgb,
        times the ray's weight: the ambient, or the thesis's colour where the
        scene has no lights; the number of shadow rays; the hit: point,
        normal, cos_i, inside; keep; the children: kr and kt after Fresnel,
        the refracted direction, and prune's answer)."""
        ox, oy, oz = rays_f[0, slot], rays_f[1, slot], rays_f[2, slot]
        dx, dy, dz = rays_f[3, slot], rays_f[4, slot], rays_f[5, slot]
        wr, wg, wb, slack = rays_f[6, slot], rays_f[7, slot], rays_f[8, slot], rays_f[9, slot]
        px, py, pz, nx, ny, nz, cos_i, inside = surface(ox, oy, oz, dx, dy, dz, t, i, spheres)
        kr = materials[REFLECT, i]
        kt = materials[TRANSMIT, i]
        keep = ONE - kr - kt
        red = ZERO
        green = ZERO
        blue = ZERO
        n_shadows = 0
        if params[P_LIGHTS] > ZERO:
            if shows(i, keep, spheres, materials):
                ar, ag, ab = colour(spheres, i)
                sx, sy, sz = lifted(px, py, pz, nx, ny, nz)
                red = wr * (keep * (params[P_AMBIENT] * ar))
                green = wg * (keep * (params[P_AMBIENT + 1] * ag))
                blue = wb * (keep * (params[P_AMBIENT + 2] * ab))
                for light in range(np.int32(params[P_LIGHTS])):
                    samples, share = light_samples(light, lights, params)
                    for s in range(samples):
                        facing = toward(sx, sy, sz, nx, ny, nz, light, s, share, lights, pattern)[4]
                        if facing > ZERO:
                            n_shadows += 1
        else:
            lr, lg, lb = colour(spheres, i)
            lr, lg, lb = shade_hit(lr, lg, lb, rim(spheres, i), d)
            red = wr * (keep * lr)
            green = wg * (keep * lg)
            blue = wb * (keep * lb)
        cast_r = False
        cast_t = False
        slack_r = ZERO
        slack_t = ZERO
        tx = ZERO
        ty = ZERO
        tz = ZERO
        if rays_i[R_DEPTH, slot] < max_depth and (kr > ZERO or kt > ZERO):
            kr, kt, tx, ty, tz, cast_r, slack_r, cast_t, slack_t = branches(
                dx, dy, dz, nx, ny, nz, cos_i, inside, kr, kt, materials[IOR, i], max(wr, max(wg, wb)), slack
            )
        return (red, green, blue, n_shadows, px, py, pz, nx, ny, nz, cos_i, inside, keep, kr, kt, tx, ty, tz,
                cast_r, slack_r, cast_t, slack_t)  # fmt: skip

    @jit
    def put_shadows(shadows_f, shadows_i, base, capacity, rays_f, rays_i, slot, i, px, py, pz, nx, ny, nz, inside,
                    keep, spheres, materials, lights, pattern, params):  # fmt: skip
        """The shadow rays of the hit that shade() counted, into slots base,
        base + 1, ... (those under capacity), each with the light it brings
        if unblocked: the ray's weight times the sample's diffuse (what
        keep leaves of it) and specular light."""
        dx, dy, dz = rays_f[3, slot], rays_f[4, slot], rays_f[5, slot]
        wr, wg, wb = rays_f[6, slot], rays_f[7, slot], rays_f[8, slot]
        pixel = rays_i[R_PIXEL, slot]
        kdr, kdg, kdb = colour(spheres, i)
        kdr, kdg, kdb = keep * kdr, keep * kdg, keep * kdb
        ks = materials[SPECULAR, i]
        shininess = materials[SHININESS, i]
        px, py, pz = lifted(px, py, pz, nx, ny, nz)  # where shade() counted them from
        k = base
        for light in range(np.int32(params[P_LIGHTS])):
            samples, share = light_samples(light, lights, params)
            for s in range(samples):
                lx, ly, lz, dist, facing, cr, cg, cb = toward(px, py, pz, nx, ny, nz, light, s, share, lights, pattern)
                if facing <= ZERO:
                    continue
                if k < capacity:
                    g = glint(ks, shininess, facing, nx, ny, nz, -dx, -dy, -dz, lx, ly, lz)
                    light_r = wr * (cr * kdr * facing + cr * g)
                    light_g = wg * (cg * kdg * facing + cg * g)
                    light_b = wb * (cb * kdb * facing + cb * g)
                    put(shadows_f, k, (px, py, pz, lx, ly, lz, dist, light_r, light_g, light_b))
                    shadows_i[0, k] = pixel
                    shadows_i[1, k] = i
                    shadows_i[2, k] = 1 if inside else 0
                k += 1

    @jit
    def put_children(next_f, next_i, base, capacity, rays_f, rays_i, slot, i, px, py, pz, nx, ny, nz, cos_i, inside,
                     kr, kt, tx, ty, tz, cast_r, slack_r, cast_t, slack_t):  # fmt: skip
        """The children shade() chose into slots base (and base + 1) of the
        next wave's queue, where under capacity: the refraction first, then
        the reflection, as the pixel program pushes them."""
        dx, dy, dz = rays_f[3, slot], rays_f[4, slot], rays_f[5, slot]
        wr, wg, wb = rays_f[6, slot], rays_f[7, slot], rays_f[8, slot]
        pixel = rays_i[R_PIXEL, slot]
        depth = rays_i[R_DEPTH, slot] + 1
        offset = OFFSET * (abs(px) + abs(py) + abs(pz))
        k = base
        if cast_t:
            if k < capacity:
                # it goes through the surface: from outside into the sphere, or out of it
                put_ray(next_f, next_i, k, px - offset * nx, py - offset * ny, pz - offset * nz, tx, ty, tz,
                        wr * kt, wg * kt, wb * kt, slack_t, pixel, depth, REFRACTION, i,
                        0 if inside else 1)  # fmt: skip
            k += 1
        if cast_r and k < capacity:
            two_cos = TWO * cos_i
            put_ray(next_f, next_i, k, px + offset * nx, py + offset * ny, pz + offset * nz, dx + two_cos * nx,
                    dy + two_cos * ny, dz + two_cos * nz, wr * kr, wg * kr, wb * kr, slack_r, pixel, depth,
                    REFLECTION, i, 1 if inside else 0)  # fmt: skip

    return SimpleNamespace(
        fixed=fixed,
        resolve=resolve,
        emit_primary=emit_primary,
        extend=extend,
        unblocked=unblocked,
        missed=missed,
        shade=shade,
        put_shadows=put_shadows,
        put_children=put_children,
    )
