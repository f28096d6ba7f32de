"""An independent float64 NumPy model of the thesis ray tracer, for the tests.

It follows design.md's conventions and the thesis's literal formulas, in float64,
and shares no code with raybench's kernels. Besides the picture it bounds how far
a float32 kernel may stray, so tests can tell a real disagreement from rounding.
"""

from dataclasses import dataclass

import numpy as np

EPS32 = float(np.finfo(np.float32).eps)
# Safety factor over the leading-order rounding terms of the float32 kernel.
K = 32.0


@dataclass
class Reference:
    hits: np.ndarray  # (H, W) nearest sphere with t > 0, -1 for none
    color: np.ndarray  # (H, W, 3) float64 colour before clamping
    candidates: list  # per ambiguous pixel (y, x): set of acceptable hit indices
    ambiguous: np.ndarray  # (H, W) bool: rounding could change which sphere wins
    color_tol: np.ndarray  # (H, W) bound on the float32 colour error


def rays(camera, width, height):
    pos = np.array(camera.position, float)
    f = np.array(camera.look_at, float) - pos
    f /= np.linalg.norm(f)
    r = np.cross(f, np.array(camera.up, float))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    ph = 2 * np.tan(np.radians(camera.fov_deg) / 2)
    pw = ph * width / height
    xs = (np.arange(width) + 0.5) / width - 0.5
    ys = 0.5 - (np.arange(height) + 0.5) / height
    d = f + r * pw * xs[None, :, None] + u * ph * ys[:, None, None]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    return pos, d


def to_bytes(c):
    return np.floor(np.clip(c, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)


def trace(scene, camera, width, height, pixels=None) -> Reference:
    """The reference frame; with pixels (flat indices y * width + x), only those
    pixels, as flat arrays in that order."""
    s = scene.spheres.astype(np.float64)
    centers, radii, colors = s[0:3].T, s[3], s[4:7].T
    pos, d = rays(camera, width, height)
    dirs = d.reshape(-1, 3)
    flat = np.arange(len(dirs)) if pixels is None else np.asarray(pixels)
    dirs = dirs[flat]
    n = len(radii)
    npix = len(dirs)
    hits = np.full(npix, -1)
    best_d = np.zeros(npix)
    ambiguous = np.zeros(npix, bool)
    candidates = {}
    color_tol = np.full(npix, 1e-6)
    if n:
        eo = centers - pos  # (n, 3)
        eo2 = np.einsum("ij,ij->i", eo, eo)  # (n,)
        norm_eo = np.sqrt(eo2)
        for start in range(0, npix, 4096):
            dd = dirs[start : start + 4096]
            v = dd @ eo.T  # (p, n)
            disc = radii**2 - (eo2 - v * v)  # the thesis's formula
            hit = disc >= 0
            dist = np.sqrt(np.where(hit, disc, 0.0))
            t = v - dist
            valid = hit & (t > 0)
            tt = np.where(valid, t, np.inf)
            idx = np.argmin(tt, axis=1)
            got = np.isfinite(tt[np.arange(len(dd)), idx])
            hits[start : start + len(dd)] = np.where(got, idx, -1)
            best_d[start : start + len(dd)] = dist[np.arange(len(dd)), idx]

            # How far could float32 move each quantity? (leading order, times K)
            err_disc = K * EPS32 * (norm_eo * (radii + np.sqrt(np.maximum(radii**2 - disc, 0))) + radii**2)
            err_dist = np.where(
                dist > 0, np.minimum(err_disc / (2 * np.maximum(dist, 1e-300)), np.sqrt(err_disc)), np.sqrt(err_disc)
            )
            err_t = K * EPS32 * (norm_eo + dist) + err_dist
            maybe_hit = (disc >= -err_disc) & (t > -err_t)
            sure_hit = (disc > err_disc) & (t > err_t)
            upper = np.where(sure_hit, t + err_t, np.inf).min(axis=1)
            possible = maybe_hit & (t - err_t <= upper[:, None])
            count = possible.sum(axis=1)
            nosure = ~np.isfinite(upper)
            amb = (count > 1) | ((count == 1) & nosure)
            for p in np.nonzero(amb)[0]:
                cand = set(np.nonzero(possible[p])[0].tolist())
                if nosure[p]:
                    cand.add(-1)
                candidates[start + p] = cand
            ambiguous[start : start + len(dd)] = amb
            win = np.where(got, idx, 0)
            rows = np.arange(len(dd))
            color_tol[start : start + len(dd)] = np.where(got, err_dist[rows, win] / radii[win] + 4 * EPS32, 1e-6)
    color = np.empty((npix, 3))
    miss = hits < 0
    ys, xs = np.divmod(flat, width)
    color[miss] = np.stack([xs / 1024, ys / 1024, xs / 786], axis=1)[miss]
    h = hits[~miss]
    fade = (radii[h] - best_d[~miss]) / radii[h]
    color[~miss] = colors[h] - fade[:, None]
    if pixels is not None:
        return Reference(hits, color, candidates, ambiguous, color_tol)
    cand2d = {(p // width, p % width): c for p, c in candidates.items()}
    return Reference(
        hits.reshape(height, width),
        color.reshape(height, width, 3),
        cand2d,
        ambiguous.reshape(height, width),
        color_tol.reshape(height, width),
    )


def check_frame(frame, ref: Reference, max_ambiguous=0.02, context=""):
    """Assert a raybench frame agrees with the reference: identical hit indices
    wherever rounding cannot change the winner (elsewhere one of the possible
    winners), colours within one step (more only where the reference's error
    bound for that pixel says float32 may differ by more)."""
    h, w = ref.hits.shape
    assert frame.image.shape == (h, w, 3) and frame.image.dtype == np.uint8, context
    assert frame.hits.shape == (h, w), context
    amb = ref.ambiguous
    frac = amb.mean()
    assert frac <= max_ambiguous, f"{context}: {frac:.1%} of pixels are ambiguous; the test would prove too little"
    wrong = (frame.hits != ref.hits) & ~amb
    assert not wrong.any(), (
        f"{context}: {wrong.sum()} pixels hit another sphere than the reference, "
        f"first at (y, x) = {tuple(np.argwhere(wrong)[0])}: "
        f"got {frame.hits[wrong][0]}, expected {ref.hits[wrong][0]}"
    )
    for (y, x), cand in ref.candidates.items():
        assert int(frame.hits[y, x]) in cand, (
            f"{context}: pixel ({y}, {x}) hit {frame.hits[y, x]}, not one of the possible {sorted(cand)}"
        )
    same = ~amb
    steps = np.abs(frame.image.astype(int) - to_bytes(ref.color).astype(int)).max(axis=2)
    tol_steps = ref.color_tol * 255
    allowed = np.where(tol_steps <= 0.5, 1, 1 + np.ceil(tol_steps))
    bad = same & (steps > allowed)
    assert not bad.any(), (
        f"{context}: {bad.sum()} pixels differ in colour beyond rounding, first at "
        f"{tuple(np.argwhere(bad)[0])}: got {frame.image[bad][0]}, "
        f"expected {to_bytes(ref.color)[bad][0]}"
    )
    # The wider allowance must be rare, or "within one step" would mean little.
    wide = same & (allowed > 1)
    assert wide.mean() <= max_ambiguous, f"{context}: {wide.mean():.1%} of pixels needed a colour tolerance over 1 step"
