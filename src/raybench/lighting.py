"""Lights, materials and the settings of Whitted shading (scene format
version 2), checked, and packed into the arrays the kernels read
(raybench.layout names their rows and the settings' slots; kernels/whitted.py
shades with them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import layout
from .camera import MAX_MAGNITUDE, _vector
from .errors import RaybenchError

SHADINGS = ("thesis", "whitted")
DEFAULT_DEPTH = 5
DEFAULT_SHADOW_SAMPLES = 4
MAX_SHADOW_SAMPLES = 64
# The lights a scene may have: the wgpu backend holds them in a uniform buffer
# of fixed size (and every light costs every hit its shadow rays).
MAX_LIGHTS = 64
DEFAULT_AMBIENT = (0.1, 0.1, 0.1)
MAX_INTENSITY = 1e6
MAX_SHININESS = 1e4
MAX_IOR = 100.0
# The least index of refraction: eta (an index over another) then stays
# within [1 / MAX_IOR, MAX_IOR], far from float32's under- and overflow.
MIN_IOR = 1.0 / MAX_IOR
# The area lights' sample points: fixed, so that frames are reproducible and
# devices comparable; the seed is the thesis's year.
PATTERN_SEED = 2010


def _number(value, where: str, low: float, high: float, low_open: bool = False) -> float:
    """A number in [low, high] ((low, high] with low_open); one line naming
    `where` otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise RaybenchError(f"{where}: must be a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:  # an integer past float's range
        raise RaybenchError(f"{where}: must be a finite number, got an integer of {len(str(value))} digits") from None
    if not math.isfinite(value):
        raise RaybenchError(f"{where}: must be a finite number, got {value}")
    low_ok = value > low if low_open else value >= low
    if not (low_ok and value <= high):
        bound = f"> {low:g}" if low_open else f">= {low:g}"
        raise RaybenchError(f"{where}: must be {bound} and at most {high:g}, got {value:g}")
    return value


def check_colour(value, where: str) -> tuple[float, float, float]:
    vec = _vector(value, where)
    if not all(0.0 <= c <= 1.0 for c in vec):
        raise RaybenchError(f"{where}: each channel must be in [0, 1], got {list(vec)}")
    return vec


# Each Material field's range, as Material checks it and Shading.check its row.
_RANGES = {"specular": (0.0, 1.0), "shininess": (0.0, MAX_SHININESS), "reflect": (0.0, 1.0), "transmit": (0.0, 1.0),
           "ior": (MIN_IOR, MAX_IOR)}  # fmt: skip


@dataclass(frozen=True)
class Material:
    """How a sphere answers light under Whitted shading; its diffuse colour
    is the sphere's colour. specular: the Phong term's weight, shininess its
    exponent; reflect and transmit: the shares of light mirrored and
    refracted (at most 1 together; Fresnel moves part of the transmitted
    share to the mirrored one); ior: the index of refraction."""

    specular: float = 0.0
    shininess: float = 32.0
    reflect: float = 0.0
    transmit: float = 0.0
    ior: float = 1.5

    def __post_init__(self):
        self.check("material")

    def check(self, where: str) -> None:
        # each field kept as a Python float (a NumPy scalar given would not save as JSON)
        for key, (low, high) in _RANGES.items():
            object.__setattr__(self, key, _number(getattr(self, key), f"{where}.{key}", low, high))
        if self.reflect + self.transmit > 1.0:
            raise RaybenchError(
                f"{where}: reflect + transmit must be at most 1, got {self.reflect:g} + {self.transmit:g}"
            )

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in MATERIAL_KEYS}

    @classmethod
    def from_dict(cls, doc, where: str) -> Material:
        if not isinstance(doc, dict):
            raise RaybenchError(f"{where}: must be an object with some of {', '.join(MATERIAL_KEYS)}")
        _no_unknown(doc, MATERIAL_KEYS, where)
        values = {k: _number(doc[k], f"{where}.{k}", -math.inf, math.inf) for k in doc}
        try:
            return cls(**values)
        except RaybenchError as exc:  # the field's path, not the bare "material"
            raise RaybenchError(str(exc).replace("material", where, 1)) from None


MATERIAL_KEYS = ("specular", "shininess", "reflect", "transmit", "ior")
MATTE = Material()


@dataclass(frozen=True)
class Light:
    """A point light (radius 0) or a spherical area light, which casts soft
    shadows. colour times intensity is what it sheds, the same at any
    distance (Whitted's lights: no fall-off)."""

    position: tuple[float, float, float]
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    radius: float = 0.0

    def __post_init__(self):
        self.check("light")

    def check(self, where: str) -> None:
        object.__setattr__(self, "position", _vector(self.position, f"{where}.position"))
        object.__setattr__(self, "color", check_colour(self.color, f"{where}.color"))
        object.__setattr__(self, "intensity", _number(self.intensity, f"{where}.intensity", 0.0, MAX_INTENSITY))
        object.__setattr__(self, "radius", _number(self.radius, f"{where}.radius", 0.0, MAX_MAGNITUDE))

    def to_dict(self) -> dict:
        doc = {"position": list(self.position), "color": list(self.color), "intensity": self.intensity}
        if self.radius:
            doc["radius"] = self.radius
        return doc

    @classmethod
    def from_dict(cls, doc, where: str) -> Light:
        if not isinstance(doc, dict):
            raise RaybenchError(f'{where}: must be an object with "position" and some of color, intensity, radius')
        _no_unknown(doc, ("position", "color", "intensity", "radius"), where)
        if "position" not in doc:
            raise RaybenchError(f"{where}.position: missing")
        values = {**doc}
        for key in ("intensity", "radius"):
            if key in values:
                values[key] = _number(values[key], f"{where}.{key}", -math.inf, math.inf)
        try:
            return cls(**values)
        except RaybenchError as exc:  # the field's path, not the bare "light"
            raise RaybenchError(str(exc).replace("light", where, 1)) from None


def _no_unknown(doc: dict, allowed, where: str) -> None:
    unknown = sorted(set(doc) - set(allowed))
    if unknown:
        raise RaybenchError(f"{where}.{unknown[0]}: unknown field (allowed: {', '.join(sorted(allowed))})")


def materials_array(materials, n: int) -> np.ndarray:
    """(MATERIAL_ROWS, n) float32 from n Materials (None: all matte)."""
    out = np.empty((layout.MATERIAL_ROWS, n), np.float32)
    for row, key in ((layout.SPECULAR, "specular"), (layout.SHININESS, "shininess"), (layout.REFLECT, "reflect"),
                     (layout.TRANSMIT, "transmit"), (layout.IOR, "ior")):  # fmt: skip
        out[row] = [getattr(m, key) for m in materials] if materials is not None else getattr(MATTE, key)
    return out


def lights_array(lights) -> np.ndarray:
    """(LIGHT_ROWS, L) float32; the colour rows hold colour times intensity."""
    out = np.zeros((layout.LIGHT_ROWS, max(len(lights), 1)), np.float32)
    for k, light in enumerate(lights):
        out[layout.LX : layout.LZ + 1, k] = light.position
        out[layout.LRED : layout.LBLUE + 1, k] = [c * light.intensity for c in light.color]
        out[layout.LRADIUS, k] = light.radius
    return out


def sample_pattern(samples: int) -> np.ndarray:
    """(3, samples) float32: the first `samples` of a fixed sequence of points
    spread uniformly through the unit ball, where an area light's shadow rays
    aim (scaled by its radius, moved to its centre). The same on every run."""
    rng = np.random.default_rng(PATTERN_SEED)
    points = rng.normal(size=(MAX_SHADOW_SAMPLES, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    points *= rng.uniform(0.0, 1.0, (MAX_SHADOW_SAMPLES, 1)) ** (1.0 / 3.0)
    return np.ascontiguousarray(points[: max(samples, 1)].T.astype(np.float32))


@dataclass
class Shading:
    """What a Whitted frame needs besides the spheres: the arrays the kernel
    reads (params: laid out by raybench.layout's P_ indices)."""

    materials: np.ndarray
    lights: np.ndarray
    pattern: np.ndarray
    params: np.ndarray
    depth: int
    shadow_samples: int

    @classmethod
    def of(cls, scene, depth=None, shadow_samples=None) -> Shading:
        """The arrays of scene (a Scene: of what its tracer traces, its
        spheres or its meshes' triangles; or anything with materials, one
        per primitive, lights, ambient, background and a length)."""
        if hasattr(scene, "traced"):
            scene = scene.traced()
        depth = DEFAULT_DEPTH if depth is None else check_depth(depth)
        samples = DEFAULT_SHADOW_SAMPLES if shadow_samples is None else check_shadow_samples(shadow_samples)
        params = np.zeros(layout.PARAMS, np.float32)
        params[layout.P_AMBIENT : layout.P_AMBIENT + 3] = scene.ambient
        if scene.background is None:
            params[layout.P_GRADIENT] = 1.0
        else:
            params[layout.P_BACKGROUND : layout.P_BACKGROUND + 3] = scene.background
        params[layout.P_DEPTH] = depth
        params[layout.P_SAMPLES] = samples
        params[layout.P_LIGHTS] = len(scene.lights)
        return cls(
            materials=materials_array(scene.materials, len(scene)),
            lights=lights_array(scene.lights),
            pattern=sample_pattern(samples),
            params=params,
            depth=depth,
            shadow_samples=samples,
        )

    def check(self, spheres: int) -> None:
        """Refuse, in one line, a Shading that does not fit a scene of
        `spheres` spheres (one made with Shading.of for another scene, or
        by hand), or whose arrays say what no Material, Light or setting
        can: the kernels index and divide by them unchecked."""
        fix = "make it with Shading.of(scene) for the scene traced"

        def array(name: str, rows: int, columns: int | None) -> np.ndarray:
            value = getattr(self, name)
            if (
                not isinstance(value, np.ndarray)
                or value.dtype != np.float32
                or value.ndim != (1 if rows is None else 2)
                or (rows is not None and value.shape[0] != rows)
                or (columns is not None and value.shape[-1] != columns)
                or value.shape[-1] < 1
                or not value.flags.c_contiguous
            ):
                want = f"({rows}, {'n' if columns is None else columns})" if rows is not None else f"({columns},)"
                got = f"{value.shape} {value.dtype}" if isinstance(value, np.ndarray) else type(value).__name__
                raise RaybenchError(f"shading: {name} must be a C-contiguous {want} float32 array, got {got}; {fix}")
            return value

        params = array("params", None, layout.PARAMS)
        if spheres and getattr(self.materials, "shape", (0, 0))[-1] != spheres:
            got = getattr(self.materials, "shape", ("?", "?"))[-1]
            raise RaybenchError(f"shading: made for a scene of {got} spheres, this one has {spheres}; {fix}")
        materials = array("materials", layout.MATERIAL_ROWS, spheres) if spheres else None
        lights = array("lights", layout.LIGHT_ROWS, None)
        pattern = array("pattern", 3, None)
        depth, samples, count = (float(params[k]) for k in (layout.P_DEPTH, layout.P_SAMPLES, layout.P_LIGHTS))
        if depth != self.depth or samples != self.shadow_samples:
            raise RaybenchError(f"shading: depth and shadow_samples differ from its params; {fix}")
        check_depth(self.depth)
        check_shadow_samples(self.shadow_samples)
        if not (count == int(count) and 0 <= count <= min(lights.shape[1], MAX_LIGHTS)):
            raise RaybenchError(f"shading: {count:g} lights in params, {lights.shape[1]} in its lights array; {fix}")
        if pattern.shape[1] < self.shadow_samples:
            raise RaybenchError(f"shading: {pattern.shape[1]} sample points for {self.shadow_samples} samples; {fix}")
        ranges = [("params", params[: layout.P_GRADIENT], 0.0, 1.0), ("pattern", pattern, -1.0, 1.0),
                  ("lights", lights[layout.LX : layout.LZ + 1], -MAX_MAGNITUDE, MAX_MAGNITUDE),
                  ("lights", lights[layout.LRED : layout.LBLUE + 1], 0.0, MAX_INTENSITY),
                  ("lights", lights[layout.LRADIUS], 0.0, MAX_MAGNITUDE)]  # fmt: skip
        if materials is not None:
            rows = {"specular": layout.SPECULAR, "shininess": layout.SHININESS, "reflect": layout.REFLECT,
                    "transmit": layout.TRANSMIT, "ior": layout.IOR}  # fmt: skip
            for key, (low, high) in _RANGES.items():
                ranges.append((f"materials' {key}", materials[rows[key]], low, high))
            shares = materials[layout.REFLECT] + materials[layout.TRANSMIT]
            ranges.append(("materials' reflect + transmit", shares, 0.0, 1.0 + 1e-6))
        for name, values, low, high in ranges:
            if values.size and not (values.min() >= low and values.max() <= high):  # NaN fails both
                raise RaybenchError(f"shading: {name} must be in [{low:g}, {high:g}]; {fix}")


def _integer(value, where: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise RaybenchError(f"{where}: must be an integer from {low} to {high}, got {value!r}")
    return int(value)


def check_depth(depth) -> int:
    return _integer(depth, "depth", 0, layout.MAX_RAY_DEPTH)


def check_shadow_samples(samples) -> int:
    return _integer(samples, "shadow_samples", 1, MAX_SHADOW_SAMPLES)


def check_shading(shading) -> str:
    if not isinstance(shading, str) or shading not in SHADINGS:  # (an array's `in` is element-wise)
        raise RaybenchError(f"shading: must be one of {', '.join(SHADINGS)}, got {shading!r}")
    return shading
