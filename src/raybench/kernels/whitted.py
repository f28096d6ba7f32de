"""Whitted shading (Whitted 1980; the thesis's "Shadow Rays" and "Reflective
Rays"): local light with shadow rays, then mirror reflection and refraction,
traced iteratively from a bounded stack of pending rays, which a GPU thread
can hold (no recursion).

A pixel's rays, each counted by kind:
- the primary ray;
- shadow rays, any-hit, from each hit point towards each light: one to a
  point light, `samples` to an area light (a sphere), at the fixed points of
  lighting.sample_pattern, so a frame is the same on every run and device;
- a reflected ray where the material reflects or Fresnel sends light back;
- a refracted ray (Snell's law) where it transmits, unless the angle is past
  the critical one (total internal reflection: all of it is reflected).
Shadow rays are cast only from a surface whose own light can show (some of
its weight left for its colour, or a specular glint): a perfect mirror or
clear glass casts none. The exact dielectric Fresnel equations (unpolarised
light, the mean of the s and p reflectances) split a transmitting
material's weight between the two, so glass of the surrounding index
(ior 1) reflects nothing and vanishes.

A ray is not spawned past `depth` bounces. Under that, a branch is dropped
only from a budget: each pixel may drop branches whose weights (the product
of the coefficients along the path, the largest channel) add up to at most
CUTOFF, half a byte's step, so the dropped light together cannot move the
pixel by a byte where no light is brighter than 1. The budget travels with
the rays (`slack`): a hit drops its lighter child, then the other, while each
fits in what is left of its ray's slack, and the children it keeps share the
rest equally (`prune`). A subtree never drops more than the slack it was
given, so the whole pixel never drops more than CUTOFF; and the rule needs
nothing but the ray itself, so a wavefront of rays (kernels/wavefront.py)
drops exactly the branches the per-pixel stack drops.

Where the scene has no lights, a hit's local colour is the thesis's own
(shade.shade_hit), so a scene of neither lights nor mirrors nor glass gives
the thesis's picture bit for bit.

Self-intersection: a secondary ray starts at the hit point, moved by OFFSET
of its coordinates' magnitude to the side it leaves on (what float32 can
resolve there), and it skips the sphere it leaves, or for a ray going into
that sphere takes only its far root (traverse.leaf_test): a sphere is
convex, so this holds for grazing rays and for tiny or huge radii, where
no offset alone can.
"""

import math
from types import SimpleNamespace

import numpy as np

from ..layout import (
    IOR,
    LBLUE,
    LGREEN,
    LRADIUS,
    LRED,
    LX,
    LY,
    LZ,
    MAX_RAY_DEPTH,
    P_AMBIENT,
    P_BACKGROUND,
    P_DEPTH,
    P_GRADIENT,
    P_LIGHTS,
    P_SAMPLES,
    PRIMARY,
    REFLECT,
    REFLECTION,
    REFRACTION,
    SHININESS,
    SPECULAR,
    TRANSMIT,
)
from .constants import FAR, ONE, TWO, ZERO

# Pending rays a pixel may hold: a ray at depth k leaves at most one sibling
# pending on each level above it and pushes two, so MAX_DEPTH + 1 suffice.
MAX_DEPTH = MAX_RAY_DEPTH
RAY_STACK = MAX_DEPTH + 2
# A pending ray: origin, direction, weight (rgb) and slack as float32 ...
RAY_FLOATS = 10
# ... and its depth, kind, the sphere it leaves and whether it goes into it.
RAY_INTS = 4
# The weight a pixel may drop in all, half a byte's step: together the dropped
# branches cannot change the pixel (the module's docstring).
CUTOFF = np.float32(0.5 / 255.0)
# Keeps Fresnel's quotients finite where both cosines are 0 (a grazing ray
# into index-matched glass), giving reflectance 0 there as everywhere else.
FRESNEL_TINY = np.float32(1e-30)
# The offset of a secondary ray's origin, of |P|_1: 16 float32 epsilons.
OFFSET = np.float32(2.0**-19)


def per_ray(jit, find, toward):
    """The shadow rays of a hit to one light a ray at a time, each through
    `find` as it is cast (the GPUs'; the default of make's `shadows`):
    (cast, blocked), the pair that local_light calls. cast(...), before the
    light's samples, traces nothing (0); blocked(batch, s, ...) walks sample
    s's ray, stopping at its first blocker."""

    @jit
    def cast(px, py, pz, nx, ny, nz, light, samples, share, own, own_inside, spheres, count, lights, pattern, tree,
             stack_row, stack_t):  # fmt: skip
        return 0

    @jit
    def blocked(batch, s, px, py, pz, lx, ly, lz, dist, own, own_inside, spheres, count, tree, stack_row, stack_t):
        blocker, _t, _d = find(px, py, pz, lx, ly, lz, dist, True, own, own_inside, spheres, count, tree, stack_row,
                               stack_t)  # fmt: skip
        return blocker >= 0

    return cast, blocked


def make(jit, call, search, prim, shade_hit, shade_miss, shadows=per_ray, name=""):
    """Whitted's pixel program over `search`, the nearest (or any) hit of
    any ray: through the tree or over every sphere (trace.search_tree and
    search_all), one program for each, so neither carries the other's code;
    and the parts of it that the wavefront's stages share (a namespace).
    prim: the primitive's compiled functions (kernels/primitives): the
    surface at a hit, and what the thesis's shading divides by.
    shadows(jit, find, toward): how a hit's shadow rays to one light are
    traced, the pair (cast, blocked) of per_ray's shape: per_ray by default;
    the CPU's packets (kernels/shadow_packets.py) trace a light's samples together in
    cast, and blocked reads the answer. name: told to find's symbol, where
    one process holds two programs over one search (the note on find)."""

    # `find` is the program's one call boundary on the CPU (call: a plain
    # numba.njit there; every other function is inlined into the kernel): the
    # walk inlined at both of find's call sites, the shadow rays' and the
    # others', made the kernel much longer to compile for the same
    # frame time (docs/notes/startup.md#time-to-the-first-picture-issue-15).
    def find(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row, stack_t):
        """The nearest sphere (or, any_hit, any) with 0 < t < t_max along a
        secondary ray: (index or -1, t, half-chord)."""
        return search(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row, stack_t)

    # Each program's find named after its search. Numba names a compiled
    # function's symbol by its qualified name and a counter of the process
    # that compiled it, so two programs' finds, compiled into the disk cache
    # by different processes, could carry one symbol name; loaded into one
    # process, the second kernel called the first one's find (brute force's
    # kernel walked the tree it has none of: a segfault; test_compiled).
    find.__name__ = f"find_{search.__name__}{name}"
    find.__qualname__ = find.__qualname__.replace("find", find.__name__)
    find = call(find)

    @jit
    def fresnel(cos_i, inside, ior):
        """Snell and the exact dielectric Fresnel equations at a hit, cos_i
        on the side the ray comes from: (reflectance, cos_t, eta), eta = n1 /
        n2; reflectance 1 past the critical angle (cos_t 0 there)."""
        eta = ior if inside else ONE / ior
        k = ONE - eta * eta * (ONE - cos_i * cos_i)
        if k < ZERO:  # total internal reflection
            return ONE, ZERO, eta
        cos_t = np.float32(math.sqrt(k))
        a = eta * cos_i
        rs = (a - cos_t) / max(a + cos_t, FRESNEL_TINY)
        b = eta * cos_t
        rp = (cos_i - b) / max(cos_i + b, FRESNEL_TINY)
        return np.float32(0.5) * (rs * rs + rp * rp), cos_t, eta

    @jit
    def prune(wmax, kr, kt, slack):
        """Which of a hit's two children to cast, and the slack each takes:
        (cast reflection, its slack, cast refraction, its slack). wmax: the
        ray's largest weight channel; kr, kt: the children's coefficients (0:
        no such child). The lighter child is dropped first, then the other,
        each while its weight fits in the slack left; those kept share the
        rest equally (the module's docstring)."""
        mr = wmax * kr
        mt = wmax * kt
        t_first = mt <= mr  # on a tie, the refraction first
        lighter, heavier = (mt, mr) if t_first else (mr, mt)
        drop_lighter = lighter <= slack
        if drop_lighter:
            slack -= lighter
        drop_heavier = heavier <= slack
        if drop_heavier:
            slack -= heavier
        drop_t = drop_lighter if t_first else drop_heavier
        drop_r = drop_heavier if t_first else drop_lighter
        if not drop_r and not drop_t:
            slack *= np.float32(0.5)
        return not drop_r, slack, not drop_t, slack

    @jit
    def branches(dx, dy, dz, nx, ny, nz, cos_i, inside, kr, kt, ior, wmax, slack):
        """A hit's two children (kr > 0 or kt > 0): (kr and kt after Fresnel,
        the refracted direction, then prune's answer). (nx, ny, nz): the unit
        normal on the ray's side; wmax, slack: the ray's largest weight and
        its slack."""
        tx = ZERO
        ty = ZERO
        tz = ZERO
        if kt > ZERO:
            reflectance, cos_t, eta = fresnel(cos_i, inside, ior)
            kr += kt * reflectance
            kt *= ONE - reflectance
            a = eta * cos_i - cos_t
            tx = eta * dx + a * nx
            ty = eta * dy + a * ny
            tz = eta * dz + a * nz
        cast_r, slack_r, cast_t, slack_t = prune(wmax, kr, kt, slack)
        return kr, kt, tx, ty, tz, cast_r, slack_r, cast_t, slack_t

    surface, rim, colour = prim.surface, prim.rim, prim.colour

    @jit
    def shows(i, keep, spheres, materials):
        """Whether primitive i's own light can reach the picture: some weight
        left for its colour, or a glint. Only then are its shadow rays cast."""
        red, green, blue = colour(spheres, i)
        return materials[SPECULAR, i] > ZERO or keep * max(red, max(green, blue)) > ZERO

    @jit
    def push(rays_f, rays_i, top, ox, oy, oz, dx, dy, dz, wr, wg, wb, slack, depth, kind, own, inside):
        """A pending ray onto the pixel's stack, row top of rays_f and
        rays_i: the new top."""
        floats = (ox, oy, oz, dx, dy, dz, wr, wg, wb, slack)
        for c in range(len(floats)):
            rays_f[top, c] = floats[c]
        rays_i[top, 0] = depth
        rays_i[top, 1] = kind
        rays_i[top, 2] = own
        rays_i[top, 3] = inside
        return top + 1

    @jit
    def background(fx, fy, params):
        """What a ray that meets nothing sees from pixel (fx, fy)."""
        if params[P_GRADIENT] > ZERO:
            return shade_miss(fx, fy)
        return params[P_BACKGROUND], params[P_BACKGROUND + 1], params[P_BACKGROUND + 2]

    @jit
    def light_samples(light, lights, params):
        """Shadow rays to one light: 1 to a point light, the frame's samples
        to an area light; and each one's share of the light."""
        samples = np.int32(params[P_SAMPLES]) if lights[LRADIUS, light] > ZERO else 1
        return samples, ONE / np.float32(samples)

    @jit
    def toward(px, py, pz, nx, ny, nz, light, s, share, lights, pattern):
        """The shadow ray from (px, py, pz) to sample s of a light: (unit
        direction, length, the cosine with the normal, the sample's rgb);
        the cosine is 0 where no ray is cast: the light behind the surface,
        at the point, or dark (it adds nothing, blocked or not)."""
        radius = lights[LRADIUS, light]
        lx = lights[LX, light] + radius * pattern[0, s] - px
        ly = lights[LY, light] + radius * pattern[1, s] - py
        lz = lights[LZ, light] + radius * pattern[2, s] - pz
        dist = np.float32(math.sqrt(lx * lx + ly * ly + lz * lz))
        cr = lights[LRED, light] * share
        cg = lights[LGREEN, light] * share
        cb = lights[LBLUE, light] * share
        if dist <= ZERO or max(cr, max(cg, cb)) <= ZERO:
            return lx, ly, lz, dist, ZERO, cr, cg, cb
        lx /= dist
        ly /= dist
        lz /= dist
        facing = max(nx * lx + ny * ly + nz * lz, ZERO)
        return lx, ly, lz, dist, facing, cr, cg, cb

    cast, blocked = shadows(jit, find, toward)

    @jit
    def lifted(px, py, pz, nx, ny, nz):
        """Where a hit's shadow rays start: the hit point moved OFFSET of
        its magnitude along the unit normal on the viewer's side, the side
        every lit sample is on. Skipping the primitive a ray leaves is not
        enough for triangles: a neighbour in (or nearly in) the same plane,
        across an edge the hit point lies within rounding of, would
        otherwise block the ray at t ~ 0 (a dark line along a floor's
        diagonal)."""
        offset = OFFSET * (abs(px) + abs(py) + abs(pz))
        return px + offset * nx, py + offset * ny, pz + offset * nz

    @jit
    def glint(ks, shininess, facing, nx, ny, nz, vx, vy, vz, lx, ly, lz):
        """Phong's highlight of one light sample: the light's mirror direction
        against the viewer's."""
        if ks > ZERO:
            rv = TWO * facing * (nx * vx + ny * vy + nz * vz) - (lx * vx + ly * vy + lz * vz)
            if rv > ZERO:
                return ks * np.float32(math.pow(rv, shininess))
        return ZERO

    @jit
    def local_light(px, py, pz, nx, ny, nz, vx, vy, vz, i, inside, spheres, count, materials, lights, pattern, params,
                    tree, stack_row, stack_t):  # fmt: skip
        """The hit's diffuse (ambient and Lambert) and specular (Phong) light,
        each an rgb triple, with a shadow ray to every light sample; and the
        number of shadow rays cast. (nx, ny, nz): the unit normal on the
        viewer's side; (vx, vy, vz): the unit direction towards the viewer."""
        kr, kg, kb = colour(spheres, i)
        px, py, pz = lifted(px, py, pz, nx, ny, nz)
        dr = params[P_AMBIENT] * kr
        dg = params[P_AMBIENT + 1] * kg
        db = params[P_AMBIENT + 2] * kb
        sr = ZERO
        sg = ZERO
        sb = ZERO
        ks = materials[SPECULAR, i]
        shininess = materials[SHININESS, i]
        shadows = 0
        for light in range(np.int32(params[P_LIGHTS])):
            samples, share = light_samples(light, lights, params)
            batch = cast(px, py, pz, nx, ny, nz, light, samples, share, i, inside, spheres, count, lights, pattern,
                         tree, stack_row, stack_t)  # fmt: skip
            for s in range(samples):
                lx, ly, lz, dist, facing, cr, cg, cb = toward(px, py, pz, nx, ny, nz, light, s, share, lights, pattern)
                if facing <= ZERO:
                    continue
                shadows += 1
                if blocked(batch, s, px, py, pz, lx, ly, lz, dist, i, inside, spheres, count, tree, stack_row,
                           stack_t):  # fmt: skip
                    continue
                dr += cr * kr * facing
                dg += cg * kg * facing
                db += cb * kb * facing
                g = glint(ks, shininess, facing, nx, ny, nz, vx, vy, vz, lx, ly, lz)
                sr += cr * g
                sg += cg * g
                sb += cb * g
        return dr, dg, db, sr, sg, sb, shadows

    @jit
    def whitted_pixel(x, y, width, height, basis, primary_ray, spheres, count, materials, lights, pattern, params,
                      tree, stack_row, stack_t, rays_f, rays_i):  # fmt: skip
        """Colour (rgb, unclamped), primary hit and the rays cast by kind for
        pixel (x, y). primary_ray: trace.primary_ray's direction, given."""
        dx, dy, dz = primary_ray
        br, bg, bb = background(np.float32(x), np.float32(y), params)
        max_depth = np.int32(params[P_DEPTH])
        lit = params[P_LIGHTS] > ZERO
        red = ZERO
        green = ZERO
        blue = ZERO
        first_hit = -1
        n_primary = 0
        n_shadow = 0
        n_reflect = 0
        n_refract = 0
        top = push(rays_f, rays_i, 0, basis[0, 0], basis[0, 1], basis[0, 2], dx, dy, dz, ONE, ONE, ONE, CUTOFF,
                   0, PRIMARY, -1, 0)  # fmt: skip
        while top > 0:
            top -= 1
            ox, oy, oz = rays_f[top, 0], rays_f[top, 1], rays_f[top, 2]
            dx, dy, dz = rays_f[top, 3], rays_f[top, 4], rays_f[top, 5]
            wr, wg, wb, slack = rays_f[top, 6], rays_f[top, 7], rays_f[top, 8], rays_f[top, 9]
            depth, kind, own, own_inside = rays_i[top, 0], rays_i[top, 1], rays_i[top, 2], rays_i[top, 3]
            if kind == PRIMARY:
                n_primary += 1
            elif kind == REFLECTION:
                n_reflect += 1
            else:
                n_refract += 1
            i, t, d = find(ox, oy, oz, dx, dy, dz, FAR, False, own, own_inside != 0, spheres, count, tree,
                           stack_row, stack_t)  # fmt: skip
            if kind == PRIMARY:
                first_hit = i
            if i < 0:
                red += wr * br
                green += wg * bg
                blue += wb * bb
                continue
            px, py, pz, nx, ny, nz, cos_i, inside = surface(ox, oy, oz, dx, dy, dz, t, i, spheres)
            kr = materials[REFLECT, i]
            kt = materials[TRANSMIT, i]
            keep = ONE - kr - kt
            if lit:
                if shows(i, keep, spheres, materials):
                    lr, lg, lb, sr, sg, sb, shadows = local_light(
                        px, py, pz, nx, ny, nz, -dx, -dy, -dz, i, inside, spheres, count, materials, lights, pattern,
                        params, tree, stack_row, stack_t,
                    )  # fmt: skip
                    n_shadow += shadows
                    red += wr * (keep * lr + sr)
                    green += wg * (keep * lg + sg)
                    blue += wb * (keep * lb + sb)
            else:
                lr, lg, lb = colour(spheres, i)
                lr, lg, lb = shade_hit(lr, lg, lb, rim(spheres, i), d)
                red += wr * (keep * lr)
                green += wg * (keep * lg)
                blue += wb * (keep * lb)
            if depth >= max_depth or (kr <= ZERO and kt <= ZERO):
                continue
            kr, kt, tx, ty, tz, cast_r, slack_r, cast_t, slack_t = branches(
                dx, dy, dz, nx, ny, nz, cos_i, inside, kr, kt, materials[IOR, i], max(wr, max(wg, wb)), slack
            )
            offset = OFFSET * (abs(px) + abs(py) + abs(pz))
            if cast_t:
                # it goes through the surface: from outside into the sphere, or out of it
                top = push(rays_f, rays_i, top, px - offset * nx, py - offset * ny, pz - offset * nz, tx, ty, tz,
                           wr * kt, wg * kt, wb * kt, slack_t, depth + 1, REFRACTION, i,
                           0 if inside else 1)  # fmt: skip
            if cast_r:
                two_cos = TWO * cos_i
                top = push(rays_f, rays_i, top, px + offset * nx, py + offset * ny, pz + offset * nz,
                           dx + two_cos * nx, dy + two_cos * ny, dz + two_cos * nz, wr * kr, wg * kr, wb * kr,
                           slack_r, depth + 1, REFLECTION, i, 1 if inside else 0)  # fmt: skip
        return red, green, blue, first_hit, n_primary, n_shadow, n_reflect, n_refract

    return SimpleNamespace(
        whitted_pixel=whitted_pixel,
        find=find,
        background=background,
        surface=surface,
        rim=rim,
        colour=colour,
        shows=shows,
        light_samples=light_samples,
        toward=toward,
        lifted=lifted,
        glint=glint,
        branches=branches,
    )
