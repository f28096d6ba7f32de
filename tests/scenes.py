"""Fresh random test scenes, each with the camera to view it from."""

import numpy as np

from raybench import Camera, Scene, random_spheres
from raybench.scene import SPREADS


def random_camera(rng) -> Camera:
    pos = rng.uniform(-3, 3, 3)
    look = pos + rng.normal(size=3)
    up = rng.normal(size=3)
    return Camera(tuple(pos), tuple(look), tuple(up), float(rng.uniform(20, 120)))


def colors(rng, n):
    return rng.uniform(0, 1, (n, 3))


def generated(rng, n):
    """random_spheres, the benchmark's scenes, from the default camera."""
    return random_spheres(n, int(rng.integers(2**31))), Camera()


def layouts(rng, n):
    """random_spheres in one of its denser layouts (larger overlapping
    spheres, clusters, a wide depth range), from the default camera."""
    layout = str(rng.choice([x for x in SPREADS if x != "even"]))
    return random_spheres(n, int(rng.integers(2**31)), layout=layout), Camera()


def cloud(rng, n):
    """Spheres all around a random camera: many in front, many behind it."""
    cam = random_camera(rng)
    centers = np.array(cam.position) + rng.uniform(-12, 12, (n, 3))
    radii = rng.uniform(0.2, 2.5, n)
    far = np.linalg.norm(centers - cam.position, axis=1) > radii * 1.01  # camera outside all of these
    return Scene(centers[far], radii[far], colors(rng, int(far.sum()))), cam


def inside(rng, n):
    """The camera inside one big sphere, with smaller spheres inside it too."""
    cam = random_camera(rng)
    big_c = np.array(cam.position) + rng.uniform(-1, 1, 3)
    centers = [big_c] + list(np.array(cam.position) + rng.uniform(-6, 6, (n - 1, 3)))
    radii = [20.0] + list(rng.uniform(0.3, 1.5, n - 1))
    return Scene(centers, radii, colors(rng, n)), cam


def overlapping(rng, n):
    """Pairs of spheres that overlap, and pairs that touch exactly, in front of the camera."""
    half = n // 2
    a = np.stack([rng.uniform(-4, 4, half), rng.uniform(-3, 3, half), rng.uniform(8, 20, half)], axis=1)
    ra = rng.uniform(0.4, 1.5, half)
    rb = rng.uniform(0.4, 1.5, half)
    direction = rng.normal(size=(half, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    gap = np.where(np.arange(half) % 2 == 0, 1.0, rng.uniform(0.3, 0.9, half))  # touching / overlapping
    b = a + direction * ((ra + rb) * gap)[:, None]
    return Scene(np.concatenate([a, b]), np.concatenate([ra, rb]), colors(rng, 2 * half)), Camera()


def radii_mixed(rng, n):
    """Tiny (1e-3) and huge (1e4) spheres together; the huge ones are far away."""
    tiny = n // 2
    small_c = np.stack(
        [rng.uniform(-0.05, 0.05, tiny), rng.uniform(-0.04, 0.04, tiny), rng.uniform(0.1, 0.3, tiny)], axis=1
    )
    small_r = rng.uniform(5e-4, 3e-3, tiny)
    huge = n - tiny
    dirs = np.stack([rng.uniform(-0.5, 0.5, huge), rng.uniform(-0.4, 0.4, huge), np.ones(huge)], axis=1)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    huge_r = rng.uniform(2e3, 1e4, huge)
    huge_c = dirs * (huge_r * rng.uniform(1.2, 3.0, huge))[:, None]
    return Scene(np.concatenate([small_c, huge_c]), np.concatenate([small_r, huge_r]), colors(rng, n)), Camera(
        fov_deg=30
    )


KINDS = {
    "generated": generated,
    "layouts": layouts,
    "cloud": cloud,
    "inside": inside,
    "overlapping": overlapping,
    "radii_mixed": radii_mixed,
}


# Degenerate scenes for the BVH (its builder and every backend's walk), each
# with the camera to view it from.


def one_point(rng, n):
    """All spheres at one centre; half share one radius (exact ties in t)."""
    c = rng.uniform(-2, 2, 3) + np.array([0, 0, 12.0])
    radii = np.where(rng.random(n) < 0.5, 1.5, rng.uniform(0.5, 3.0, n))
    return Scene(np.tile(c, (n, 1)), radii, colors(rng, n)), Camera()


def duplicates(rng, n):
    """Copies of a few spheres at scattered indices: every hit on them is a tie."""
    base, _ = KINDS["generated"](rng, max(1, n // 4))
    pick = rng.integers(0, len(base), n)
    s = base.spheres[:, pick]
    return Scene(s[0:3].T, s[3], s[4:7].T), Camera()


def line(rng, n):
    """Centres on one line: across the view, or along it (a sight line)."""
    cam = random_camera(rng)
    p = np.array(cam.position) + rng.normal(size=3) * 2
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    if rng.random() < 0.5:  # along the camera's sight line
        d = np.array(cam.look_at) - np.array(cam.position)
        d /= np.linalg.norm(d)
        p = np.array(cam.position) + d * 3
    centers = p + np.outer(np.sort(rng.uniform(0, 20, n)), d)
    return Scene(centers, rng.uniform(0.05, 1.0, n), colors(rng, n)), cam


def one(rng, n):
    return Scene([rng.uniform(-1, 1, 3) + [0, 0, 6]], [rng.uniform(0.5, 3)], colors(rng, 1)), Camera()


def none(rng, n):
    return Scene(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))), random_camera(rng)


def chain(rng, n):
    """Centres at 20^k, k = -29..11, along each axis: every binned split (16
    bins) can only cut off the one farthest sphere, so SAH alone would build
    a chain 123 deep."""
    scale = 20.0 ** np.arange(-29, 12)
    centers = np.zeros((3 * len(scale), 3))
    for axis in range(3):
        centers[axis * len(scale) : (axis + 1) * len(scale), axis] = scale * rng.choice([-1, 1])
    radii = np.maximum(0.05 * np.abs(centers).sum(1), 1e-30)
    m = len(radii)
    pos = rng.normal(size=3)
    cam = Camera(tuple(pos / np.linalg.norm(pos) * 1e14), (0, 0, 0), tuple(rng.normal(size=3)), 60)
    return Scene(centers, radii, colors(rng, m)), cam


DEGENERATE = {"one_point": one_point, "duplicates": duplicates, "line": line, "one": one, "none": none, "chain": chain}
SCENES = {**KINDS, **DEGENERATE}
# scenes whose spheres are always in front of their camera
IN_VIEW = {"generated", "layouts", "inside", "overlapping", "radii_mixed", "one_point", "duplicates", "one"}
