"""An independent float64 NumPy model of Whitted shading, for the tests.

Written from the rules in kernels/whitted.py's docstring and the README's
scene format, recursively (as Whitted wrote it), in float64, with no code
shared with raybench's kernels: only the scene's arrays and the fixed
sample pattern (data) come from raybench.
"""

from dataclasses import dataclass

import numpy as np
from reference import rays

# The weight a pixel may drop in all, half a byte's step (the kernel's CUTOFF).
CUTOFF = 0.5 / 255.0


def fresnel(cos_i, eta):
    """Exact dielectric reflectance of unpolarised light, eta = n1 / n2: (R, cos_t), R = 1 past the critical angle."""
    k = 1.0 - eta**2 * (1.0 - cos_i**2)
    if k < 0:
        return 1.0, 0.0
    cos_t = np.sqrt(k)
    rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t) if eta * cos_i + cos_t > 0 else 0.0
    rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t) if cos_i + eta * cos_t > 0 else 0.0
    return 0.5 * (rs**2 + rp**2), cos_t


def prune(wmax, kr, kt, slack):
    """The drop budget's rule: the lighter child dropped first, then the
    other, each while its weight fits in the slack left; the kept share the
    rest. (keep reflection, keep refraction, each kept child's slack)."""
    drop = {"r": False, "t": False}
    weights = {"r": wmax * kr, "t": wmax * kt}
    for child in ("t", "r") if weights["t"] <= weights["r"] else ("r", "t"):
        if weights[child] <= slack:
            drop[child] = True
            slack -= weights[child]
    kept = (not drop["r"]) + (not drop["t"])
    return not drop["r"], not drop["t"], slack / kept if kept else slack


@dataclass
class WhittedReference:
    color: np.ndarray  # (H, W, 3) float64 before clamping
    hits: np.ndarray  # (H, W) the primary ray's sphere, -1 for none
    rays: np.ndarray  # (4,) primary, shadow, reflection, refraction rays cast
    truncated: np.ndarray  # (H, W) the weight (largest channel) that met the depth limit unspent


class Model:
    def __init__(self, scene, shading):
        s = scene.spheres.astype(np.float64)
        self.centers, self.radii, self.colors = s[0:3].T, s[3], s[4:7].T
        m = shading.materials.astype(np.float64)
        self.specular, self.shininess, self.reflect, self.transmit, self.ior = m
        self.lights = shading.lights.astype(np.float64)[:, : len(scene.lights)]
        self.pattern = shading.pattern.astype(np.float64)
        self.ambient = np.array(scene.ambient, float)
        self.background = None if scene.background is None else np.array(scene.background, float)
        self.depth = shading.depth
        self.samples = shading.shadow_samples
        self.counts = np.zeros(4, np.int64)
        self.truncated = 0.0  # the current pixel's weight stopped by the depth limit

    def first_hit(self, o, d, t_max, own, own_inside):
        """(index, t) of the nearest crossing ahead, 0 < t < t_max; the
        sphere the ray leaves is skipped, or met at its far root when the ray
        goes into it."""
        if not len(self.radii):
            return -1, np.inf
        eo = self.centers - o
        v = eo @ d
        perp = eo - v[:, None] * d
        disc = self.radii**2 - np.einsum("ij,ij->i", perp, perp)
        root = np.sqrt(np.maximum(disc, 0.0))
        near, far = v - root, v + root
        t = np.where(near > 0, near, far)
        if own >= 0:
            t[own] = far[own] if own_inside else -1.0
        t = np.where((disc >= 0) & (t > 0) & (t < t_max), t, np.inf)
        i = int(np.argmin(t))
        return (i, t[i]) if np.isfinite(t[i]) else (-1, np.inf)

    def local(self, p, n, view, i, inside):
        kd = self.colors[i]
        diffuse = self.ambient * kd
        specular = np.zeros(3)
        for k in range(self.lights.shape[1]):
            centre, power, radius = self.lights[0:3, k], self.lights[3:6, k], self.lights[6, k]
            points = centre[:, None] + radius * self.pattern[:, : self.samples] if radius > 0 else centre[:, None]
            share = 1.0 / points.shape[1]
            for q in points.T:
                to_light = q - p
                dist = np.linalg.norm(to_light)
                if dist <= 0:
                    continue
                l_dir = to_light / dist
                facing = n @ l_dir
                if facing <= 0 or power.max() <= 0:
                    continue
                self.counts[1] += 1
                if self.first_hit(p, l_dir, dist, i, inside)[0] >= 0:
                    continue
                diffuse = diffuse + power * share * kd * facing
                mirror = 2 * facing * n - l_dir  # the light's reflection, against the viewer
                rv = mirror @ view
                if self.specular[i] > 0 and rv > 0:
                    specular = specular + power * share * self.specular[i] * rv ** self.shininess[i]
        return diffuse, specular

    def radiance(self, o, d, weight, slack, depth, own, own_inside, pixel_background):
        i, t = self.first_hit(o, d, np.inf, own, own_inside)
        if i < 0:
            return pixel_background, i
        p = o + t * d
        n = (p - self.centers[i]) / np.linalg.norm(p - self.centers[i])
        cos_i = -(n @ d)
        inside = cos_i < 0
        if inside:
            n, cos_i = -n, -cos_i
        kr, kt = self.reflect[i], self.transmit[i]
        keep = 1.0 - kr - kt
        if self.lights.shape[1]:
            # shadow rays only from a surface whose own light can show
            if self.specular[i] > 0 or keep * self.colors[i].max() > 0:
                diffuse, specular = self.local(p, n, -d, i, inside)
                color = keep * diffuse + specular
            else:
                color = np.zeros(3)
        else:  # no lights: the thesis's colour, darkened towards the rim
            chord = self.centers[i] - o
            v = chord @ d
            half_chord = np.sqrt(max(self.radii[i] ** 2 - (chord @ chord - v * v), 0.0))
            color = keep * (self.colors[i] - (self.radii[i] - half_chord) / self.radii[i])
        if kr <= 0 and kt <= 0:
            return color, i
        if depth >= self.depth:
            self.truncated += weight.max() * (kr + kt)
            return color, i
        refracted = None
        if kt > 0:
            eta = self.ior[i] if inside else 1.0 / self.ior[i]
            reflectance, cos_t = fresnel(cos_i, eta)
            kr, kt = kr + kt * reflectance, kt * (1.0 - reflectance)
            refracted = eta * d + (eta * cos_i - cos_t) * n
        keep_r, keep_t, child_slack = prune(weight.max(), kr, kt, slack)
        if keep_t:
            self.counts[3] += 1
            light, _ = self.radiance(p, refracted, weight * kt, child_slack, depth + 1, i, not inside, pixel_background)
            color = color + kt * light
        if keep_r:
            self.counts[2] += 1
            reflected = d + 2 * cos_i * n
            light, _ = self.radiance(p, reflected, weight * kr, child_slack, depth + 1, i, inside, pixel_background)
            color = color + kr * light
        return color, i


def trace(scene, shading, camera, width, height) -> WhittedReference:
    model = Model(scene, shading)
    pos, dirs = rays(camera, width, height)
    color = np.zeros((height, width, 3))
    hits = np.full((height, width), -1)
    truncated = np.zeros((height, width))
    for y in range(height):
        for x in range(width):
            background = model.background if model.background is not None else np.array([x / 1024, y / 1024, x / 786])
            model.counts[0] += 1
            model.truncated = 0.0
            color[y, x], hits[y, x] = model.radiance(pos, dirs[y, x], np.ones(3), CUTOFF, 0, -1, False, background)
            truncated[y, x] = model.truncated
    return WhittedReference(color, hits, model.counts, truncated)
