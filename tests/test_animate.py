"""raybench.animate: spheres on circles through their starting centres, the
same for a seed and a time."""

import numpy as np
import pytest

import raybench
from raybench import animate


def test_orbits_are_circles_through_the_start(rng):
    """A sphere at time t lies at chord 2 a |sin(w t / 2)| from its start (a
    circle of radius a = AMPLITUDE radii, angular speed w), in the plane of
    its u and v; radii and colours stay; time 0 is the scene."""
    spheres = raybench.random_spheres(int(rng.integers(1, 500)), int(rng.integers(2**31))).spheres
    orbits = animate.Orbits(spheres, int(rng.integers(2**31)))
    assert np.array_equal(orbits.at(0.0)[:3], spheres[:3])
    t = float(rng.uniform(-100, 100))
    at = orbits.at(t)
    assert np.array_equal(at[3:], spheres[3:])
    step = at[:3].astype(np.float64) - spheres[:3]
    a = animate.AMPLITUDE * spheres[3].astype(np.float64)
    chord = 2 * a * np.abs(np.sin(orbits.omega * t / 2))
    slack = 1e-6 * (np.abs(spheres[:3]).sum(0) + a)  # the float32 rounding of the centres
    assert np.all(np.abs(np.linalg.norm(step, axis=0) - chord) <= slack)
    normal = np.cross(orbits.u, orbits.v)
    assert np.all(np.abs((step.T * normal).sum(1)) <= slack)
    periods = 2 * np.pi / orbits.omega
    assert periods.min() >= animate.PERIOD_S[0] and periods.max() <= animate.PERIOD_S[1]


def test_same_seed_and_time_same_spheres(rng):
    spheres = raybench.random_spheres(200, 1).spheres
    seed, t = int(rng.integers(2**31)), float(rng.uniform(0, 60))
    assert np.array_equal(animate.Orbits(spheres, seed).at(t), animate.Orbits(spheres, seed).at(t))
    assert not np.array_equal(animate.Orbits(spheres, seed).at(t), animate.Orbits(spheres, seed + 1).at(t))


@pytest.mark.parametrize("seed,t,match", [(-1, 0.0, "seed"), (0, float("nan"), "time")])
def test_bad_seed_or_time_is_one_line(seed, t, match):
    with pytest.raises(raybench.RaybenchError, match=match):
        animate.Orbits(raybench.random_spheres(3).spheres, seed).at(t)
