"""Scenes of spheres: structure-of-arrays float32, JSON load/save, a generator.

The kernels read one (7, n) float32 array: rows x, y, z, radius, red, green,
blue (raybench.layout names them). Keeping the rows contiguous lets a kernel
stream one field for all spheres and hands every backend the same buffer
without repacking. Format version 2 adds what Whitted shading reads: lights,
a material per sphere, the ambient light and the background
(raybench.lighting); a version-1 file loads and renders as it always did.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np

from . import lighting
from .camera import MAX_MAGNITUDE, Camera
from .errors import RaybenchError, shown
from .fields import no_unknown as _no_unknown
from .fields import numbers as _numbers
from .files import read_json, write_atomic
from .host import host_available_bytes
from .layout import BLUE, CX, CZ, RADIUS, RED
from .scene_meshes import SceneMesh, Traced, merged, merged_materials, read_meshes, traced

FORMAT = "raybench-scene"
VERSION = 3
# Files without lights, materials, ambient or background are written as
# version 1, which every raybench reads; only a scene with meshes needs 3.
VERSIONS = (1, 2, 3)
MAX_GENERATED = 100_000_000
# random_spheres fills the view of a picture this wide, about this many times over.
ASPECT = 16 / 10
# Peak bytes per sphere while random_spheres works without materials, as
# measured; with materials it needs more than this
# (docs/notes/startup.md#figures-moved-from-the-sources-comments).
GENERATE_BYTES = 256
COVERAGE = 2.0
# The thesis's test 7, a scene that grows every frame: random_spheres(last,
# seed) traced from `first` spheres, `step` more a frame (first, last, step).
# The benchmark's ramp and the viewer's both take it from here.
RAMP = (10, 1000, 10)

_TOP_KEYS = {"format", "version", "spheres", "camera"}
_SPHERE_KEYS = {"center", "radius", "color"}
# What version 2 adds.
_TOP_KEYS_2 = _TOP_KEYS | {"lights", "ambient", "background"}
_SPHERE_KEYS_2 = _SPHERE_KEYS | {"material"}
# What version 3 adds: meshes (scene_meshes), beside the spheres or instead of them.
_TOP_KEYS_3 = _TOP_KEYS_2 | {"meshes"}
_CAMERA_KEYS = {"position", "look_at", "up", "fov_deg"}


class Scene:
    """n spheres, and optionally the camera the scene was saved with; for
    Whitted shading, lights, a Material per sphere (None: all matte), the
    ambient light and the background colour (None: the thesis's gradient);
    meshes, scene_meshes.SceneMesh each (format version 3), merged as
    one triangle buffer (triangles, None without meshes) with a Material a
    triangle (triangle_materials, None: all matte). len() counts the
    spheres; traced() is what a tracer traces."""

    def __init__(
        self,
        centers,
        radii,
        colors,
        camera: Camera | None = None,
        *,
        materials=None,
        lights=(),
        ambient=lighting.DEFAULT_AMBIENT,
        background=None,
        meshes=(),
    ):
        if camera is not None and not isinstance(camera, Camera):
            raise RaybenchError(f"scene: camera must be a raybench.Camera or None, got {shown(camera)}")
        centers = _array(centers, 3, "centers")
        radii = _array(radii, None, "radii")
        colors = _array(colors, 3, "colors")
        if not (len(centers) == len(radii) == len(colors)):
            raise RaybenchError(
                f"scene: {len(centers)} centers, {len(radii)} radii and {len(colors)} colors: "
                "each sphere needs one of each"
            )
        check_values(centers, radii, colors)
        self.spheres = np.ascontiguousarray(np.concatenate([centers.T, radii[None, :], colors.T]).astype(np.float32))
        self.camera = camera
        if materials is not None:
            materials = tuple(materials)
            if len(materials) != len(radii):
                raise RaybenchError(f"scene: {len(materials)} materials for {len(radii)} spheres: give one per sphere")
            for i, m in enumerate(materials):
                if not isinstance(m, lighting.Material):
                    raise RaybenchError(f"spheres[{i}].material: must be a raybench.Material, got {type(m).__name__}")
        self.materials = materials
        self.lights = tuple(lights)
        if len(self.lights) > lighting.MAX_LIGHTS:
            raise RaybenchError(f"lights: at most {lighting.MAX_LIGHTS}, got {len(self.lights)}")
        for i, light in enumerate(self.lights):
            if not isinstance(light, lighting.Light):
                raise RaybenchError(f"lights[{i}]: must be a raybench.Light, got {type(light).__name__}")
        self.ambient = lighting.check_colour(ambient, "ambient")
        self.background = None if background is None else lighting.check_colour(background, "background")
        self.meshes = tuple(meshes)
        for i, mesh in enumerate(self.meshes):
            if not isinstance(mesh, SceneMesh):
                raise RaybenchError(f"meshes[{i}]: must be a raybench.SceneMesh, got {type(mesh).__name__}")
        self.triangle_materials = merged_materials(self.meshes)

    def __len__(self) -> int:
        return self.spheres.shape[1]

    @functools.cached_property
    def triangles(self) -> np.ndarray | None:
        """The meshes' triangles as one buffer (scene_meshes.merged), None without meshes: made
        when first asked for, as a scene of one mesh is traced from the mesh itself
        (scene_meshes.traced), which a large mesh's frame on the cpu needs no buffer of."""
        return merged(self.meshes)

    def __repr__(self) -> str:
        return f"Scene({self.summary}, camera={self.camera!r})"

    @property
    def summary(self) -> str:
        """What the scene holds, for a message: "12 spheres", "80 triangles" or both."""
        parts = [f"{len(self):,} spheres"] if len(self) or not self.meshes else []
        if self.meshes:
            parts.append(f"{sum(len(m.mesh) for m in self.meshes):,} triangles")
        return " and ".join(parts)

    def traced(self) -> Traced:
        """What a tracer traces of this scene: its spheres, its meshes'
        triangles where it has no spheres (a scene of one mesh: the mesh
        itself, painted), or both as the mixed kind (scene_meshes.traced)."""
        return traced(self)

    @property
    def centers(self) -> np.ndarray:
        return self.spheres[0:3].T

    @property
    def radii(self) -> np.ndarray:
        return self.spheres[3]

    @property
    def colors(self) -> np.ndarray:
        return self.spheres[4:7].T

    @property
    def version(self) -> int:
        """The scene format version this scene needs: 3 where it has meshes,
        else 1 unless it has lights, materials, an ambient light or a
        background of its own."""
        if self.meshes:
            return 3
        plain = (
            self.materials is None
            and not self.lights
            and self.ambient == lighting.DEFAULT_AMBIENT
            and self.background is None
        )
        return 1 if plain else 2

    def head(self, n: int) -> Scene:
        """The first n spheres of this scene, 0 <= n <= len(self), with their
        materials and the same lights."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 0 <= n <= len(self):
            raise RaybenchError(f"head: n must be an integer from 0 to {len(self)} (the spheres), got {shown(n)}")
        n = int(n)
        materials = None if self.materials is None else self.materials[:n]
        return self.replaced(
            centers=self.centers[:n], radii=self.radii[:n], colors=self.colors[:n], materials=materials
        )

    def with_lights(self, lights) -> Scene:
        """The scene with other lights: the spheres (the same float32 bits), camera,
        materials, ambient light and background as they are."""
        return self.replaced(lights=lights)

    def replaced(self, **changes) -> Scene:
        """The scene with the Scene() arguments named changed, the rest as
        they are (checked again, as Scene() checks them)."""
        fields = {"centers": self.centers, "radii": self.radii, "colors": self.colors, "camera": self.camera,
                  "materials": self.materials, "lights": self.lights, "ambient": self.ambient,
                  "background": self.background, "meshes": self.meshes}  # fmt: skip
        fields.update(changes)
        return Scene(**fields)

    def to_dict(self) -> dict:
        doc = {"format": FORMAT, "version": self.version}
        if self.camera is not None:
            doc["camera"] = self.camera.to_dict()
        if self.version > 1:
            doc["ambient"] = list(self.ambient)
            if self.background is not None:
                doc["background"] = list(self.background)
            doc["lights"] = [light.to_dict() for light in self.lights]
        # float32 -> float keeps the file exact: reloading gives the same bits.
        doc["spheres"] = [
            {"center": [float(v) for v in c], "radius": float(r), "color": [float(v) for v in k]}
            for c, r, k in zip(self.centers, self.radii, self.colors)
        ]
        if self.materials is not None:
            for sphere, material in zip(doc["spheres"], self.materials):
                if material != lighting.MATTE:
                    sphere["material"] = material.to_dict()
        if self.meshes:
            # placed and inline: a mesh file's path would not hold wherever the scene is saved
            doc["meshes"] = [mesh.to_dict() for mesh in self.meshes]
        return doc

    def save(self, path) -> None:
        write_atomic(path, json.dumps(self.to_dict(), indent=1).encode())

    @classmethod
    def from_dict(cls, doc, base=None) -> Scene:
        """The scene of a parsed scene file; base: the folder its meshes'
        files are relative to (Scene.load: the scene file's; None: the
        current folder)."""
        if not isinstance(doc, dict):
            raise RaybenchError(f'scene: must be a JSON object with "format": "{FORMAT}", got {type(doc).__name__}')
        if doc.get("format") != FORMAT:
            raise RaybenchError(f'format: must be "{FORMAT}", got {shown(doc.get("format"))}')
        version = doc.get("version")
        if version not in VERSIONS or isinstance(version, bool):
            raise RaybenchError(f"version: this raybench reads versions 1 to 3, got {shown(version)}")
        _no_unknown(doc, (_TOP_KEYS, _TOP_KEYS_2, _TOP_KEYS_3)[version - 1], "")
        if "spheres" not in doc and not (version == 3 and "meshes" in doc):
            raise RaybenchError('spheres: missing (a list of {"center", "radius", "color"} objects)')
        spheres = doc.get("spheres", [])
        if not isinstance(spheres, list):
            raise RaybenchError('spheres: must be a list of {"center", "radius", "color"} objects')
        n = len(spheres)
        centers = np.empty((n, 3))
        radii = np.empty(n)
        colors = np.empty((n, 3))
        materials = [lighting.MATTE] * n
        for i, s in enumerate(spheres):
            where = f"spheres[{i}]"
            if not isinstance(s, dict):
                raise RaybenchError(f'{where}: must be an object with "center", "radius" and "color"')
            _no_unknown(s, _SPHERE_KEYS_2 if version >= 2 else _SPHERE_KEYS, where + ".")
            if "material" in s:
                materials[i] = lighting.Material.from_dict(s["material"], f"{where}.material")
            for key in ("center", "radius", "color"):
                if key not in s:
                    raise RaybenchError(f"{where}.{key}: missing")
            centers[i] = _numbers(s["center"], 3, f"{where}.center")
            radii[i] = _numbers(s["radius"], None, f"{where}.radius")
            colors[i] = _numbers(s["color"], 3, f"{where}.color")
        camera = None
        if "camera" in doc:
            cam = doc["camera"]
            if not isinstance(cam, dict):
                raise RaybenchError("camera: must be an object with position, look_at, up, fov_deg")
            _no_unknown(cam, _CAMERA_KEYS, "camera.")
            for key in ("position", "look_at", "up"):
                if key in cam:
                    _numbers(cam[key], 3, f"camera.{key}")
            if "fov_deg" in cam:
                _numbers(cam["fov_deg"], None, "camera.fov_deg")
            camera = Camera(**cam)
        extra = {}
        if version >= 2:
            lights = doc.get("lights", [])
            if not isinstance(lights, list):
                raise RaybenchError('lights: must be a list of {"position", "color", "intensity", "radius"} objects')
            extra["lights"] = [lighting.Light.from_dict(x, f"lights[{k}]") for k, x in enumerate(lights)]
            if any(m != lighting.MATTE for m in materials):
                extra["materials"] = materials
            if "ambient" in doc:
                extra["ambient"] = _numbers(doc["ambient"], 3, "ambient")
            if "background" in doc:
                extra["background"] = _numbers(doc["background"], 3, "background")
        if version == 3:
            extra["meshes"] = read_meshes(doc.get("meshes", []), None if base is None else Path(base))
        return cls(centers, radii, colors, camera, **extra)

    @classmethod
    def load(cls, path) -> Scene:
        path = Path(path)
        doc = read_json(path, "scene file")
        try:
            return cls.from_dict(doc, path.parent)
        except RaybenchError as exc:
            raise RaybenchError(f"{path}: {exc}") from None


# The smallest positive float32 (a subnormal): any smaller radius is stored as 0.
_TINY = float(np.finfo(np.float32).smallest_subnormal)


def check_values(centers, radii, colors, where: str = "") -> None:
    """The rule every sphere meets, wherever spheres come from (a scene file,
    Scene(), Renderer.update): a centre finite and at most MAX_MAGNITUDE in
    each coordinate, a radius above 0 as float32 stores it and at most
    MAX_MAGNITUDE, each colour channel in [0, 1]. centers (n, 3), radii (n,),
    colors (n, 3), of any float type; the first sphere that breaks it is one
    line, after `where` ("update: "). NaN fails every comparison, so one pass
    of reductions answers for the valid case, and only a fault is searched."""
    if not len(radii):
        return
    radius_low = np.float32(radii.min())  # as stored: a radius that rounds to 0 in float32 is no sphere
    if (
        centers.max() <= MAX_MAGNITUDE
        and centers.min() >= -MAX_MAGNITUDE
        and radius_low > 0
        and radii.max() <= MAX_MAGNITUDE
        and colors.min() >= 0.0
        and colors.max() <= 1.0
    ):
        return
    for name, values in (("center", centers), ("radius", radii)):
        bad = ~(np.isfinite(values) & (np.abs(values) <= MAX_MAGNITUDE))
        if bad.any():
            i = int(np.argwhere(bad)[0][0])
            raise RaybenchError(
                f"{where}spheres[{i}].{name}: must be finite and at most {MAX_MAGNITUDE:g} in magnitude, "
                f"got {_plain(values[i])}"
            )
    bad = ~(radii.astype(np.float32) > 0)
    if bad.any():
        i = int(np.argmax(bad))
        why = f" (0 in float32; the smallest radius is {_TINY:g})" if radii[i] > 0 else ""
        raise RaybenchError(f"{where}spheres[{i}].radius: must be > 0, got {_plain(radii[i])}{why}")
    bad = ~((colors >= 0.0) & (colors <= 1.0))
    i = int(np.argwhere(bad)[0][0])
    raise RaybenchError(f"{where}spheres[{i}].color: each channel must be in [0, 1], got {_plain(colors[i])}")


def _plain(values):
    """A number or a row of them as its type prints it: float32's shortest
    form (0.5, not 0.5034334063529968 for 0.5034334)."""
    listed = [float(str(v)) for v in np.atleast_1d(values)]
    return listed if np.ndim(values) else listed[0]


def sizes(spheres: np.ndarray) -> np.ndarray:
    """Each sphere's size in a (7, n) sphere array, (n,) float64: the length
    that what is done to a sphere is scaled by (raybench.animate's orbits),
    so that nothing outside the scene reads the radius row."""
    return spheres[RADIUS].astype(np.float64)


def check_spheres(spheres: np.ndarray, where: str = "") -> None:
    """check_values of a (7, n) sphere array, as Scene.spheres holds them
    (raybench.layout's rows)."""
    check_values(spheres[CX : CZ + 1].T, spheres[RADIUS], spheres[RED : BLUE + 1].T, where)


def _array(values, columns: int | None, name: str) -> np.ndarray:
    """values as float64 of shape (n, columns), or (n,) where columns is None:
    real numbers only (ints of any NumPy width, floats), nothing reshaped, so a
    (3, 2) array or a flat list is refused rather than read as other spheres."""
    want = "(n,)" if columns is None else f"(n, {columns})"
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as exc:  # ragged lists
        raise RaybenchError(f"scene: {name} must be an array of shape {want} of numbers ({exc})") from None
    if array.dtype.kind not in "iuf":
        raise RaybenchError(
            f"scene: {name} must be real numbers of shape {want}, got an array of {array.dtype} "
            "(booleans, complex numbers, text and None are refused)"
        )
    if array.size == 0:  # [] or np.empty(0): no spheres, whatever the shape
        return np.zeros((0,) if columns is None else (0, columns))
    if array.shape[1:] != (() if columns is None else (columns,)) or array.ndim != (1 if columns is None else 2):
        raise RaybenchError(f"scene: {name} must have shape {want}, got {array.shape}")
    return array.astype(np.float64)


def random_spheres(n: int, seed: int = 0, materials: bool = False, layout: str = "even") -> Scene:
    """n spheres in front of the default camera, sized so that any n from 10 to
    1,000,000 covers the picture about twice over: a full, varied image.

    Centres are uniform over the view of a 16:10 picture (the widest of the
    benchmark's resolutions; at 4:3 some fall outside the sides) at depths 5 to
    25; the angular radius shrinks as 1/sqrt(n) to keep the coverage constant.
    The same seed gives the same spheres on every machine.

    materials: the same spheres, lit for Whitted shading by one area light
    above and behind the camera, with mixed materials (mixed_materials).

    layout: how the spheres are spread (one of SPREADS). "even", the above, is the
    benchmark's scene; the others are denser scenes, so that a tree is not
    tuned to the even spread alone (docs/notes/bvh-walk.md#denser-scenes-issue-16-item-6):
    - "dense": the same spread with spheres 3 times larger (about 18 layers
      over the picture), most overlapping many others;
    - "clusters": tight blobs of about 100 spheres each, the blobs spread as
      "even" spreads spheres and covering about half the picture; each blob
      is several layers deep, and much of the view is empty;
    - "deep": depths from 1 to 1,000 (log-uniform) instead of 5 to 25, with
      the even layout's angular sizes, so that spheres' sizes in the scene
      span a factor of 1,000 and near small spheres hide far huge ones.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not (0 <= n <= MAX_GENERATED):
        raise RaybenchError(f"sphere count: must be an integer from 0 to {MAX_GENERATED:,}, got {shown(n)}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise RaybenchError(f"seed: must be a non-negative integer, got {shown(seed)}")
    if layout not in SPREADS:
        raise RaybenchError(f"layout: must be one of {', '.join(SPREADS)}, got {shown(layout)}")
    need = n * GENERATE_BYTES
    available = host_available_bytes()
    if need > available:
        raise RaybenchError(
            f"sphere count: {n:,} spheres need about {need / 2**30:.2f} GiB to generate, more than the "
            f"{available / 2**30:.2f} GiB this process may use; use fewer spheres"
        )
    rng = np.random.default_rng(seed)
    plane_h = 2.0 * math.tan(math.radians(30.0))
    plane_w = plane_h * ASPECT
    if layout == "even":
        centers, radii = _even(rng, n, plane_w, plane_h)
    else:
        # a stream of its own, so that "even" stays what it always drew
        centers, radii = _SPREADS[layout](np.random.default_rng([seed, 0x1A7]), n, plane_w, plane_h)
    colors = rng.uniform(0.25, 1.0, (n, 3))
    if not materials:
        return Scene(centers, radii, colors)
    return Scene(centers, radii, colors, materials=mixed_materials(n, seed), lights=[MIXED_LIGHT])


def _even(rng, n, plane_w, plane_h, scale=1.0, depths=(5.0, 25.0), log_depth=False):
    """Centres uniform over the view at the given depths (log-uniform if
    log_depth), angular radii sized for COVERAGE times scale squared."""
    if log_depth:
        depth = np.exp(rng.uniform(math.log(depths[0]), math.log(depths[1]), n))
    else:
        depth = rng.uniform(depths[0], depths[1], n)
    u = rng.uniform(-0.5, 0.5, n) * plane_w
    v = rng.uniform(-0.5, 0.5, n) * plane_h
    centers = np.stack([u * depth, v * depth, depth], axis=1)
    angular = scale * math.sqrt(COVERAGE * plane_w * plane_h / (math.pi * max(n, 1)))
    # Few spheres are large; none may reach the camera.
    radii = np.minimum(depth * angular * rng.uniform(0.5, 1.5, n), 0.5 * depth)
    return centers, radii


def _dense(rng, n, plane_w, plane_h):
    return _even(rng, n, plane_w, plane_h, scale=3.0)


def _deep(rng, n, plane_w, plane_h):
    return _even(rng, n, plane_w, plane_h, depths=(1.0, 1000.0), log_depth=True)


# The clusters spread: spheres a blob, and the share of the picture the blobs cover.
CLUSTER_SIZE = 100
CLUSTER_COVERAGE = 0.5


def _clusters(rng, n, plane_w, plane_h):
    k = max(1, round(n / CLUSTER_SIZE))
    hub, _ = _even(rng, k, plane_w, plane_h)
    # a blob's angular radius, and its spheres' sized to cover its disc about 4 times
    blob = math.sqrt(CLUSTER_COVERAGE * plane_w * plane_h / (math.pi * k))
    which = rng.integers(0, k, n)
    depth = hub[which, 2]
    centers = hub[which] + rng.normal(0.0, 0.5, (n, 3)) * (blob * depth)[:, None]
    per_blob = max(n / k, 1.0)
    radii = depth * blob * math.sqrt(4.0 / per_blob) * rng.uniform(0.5, 1.5, n)
    # none may reach the camera
    radii = np.minimum(radii, 0.5 * np.linalg.norm(centers, axis=1))
    return centers, radii


_SPREADS = {"dense": _dense, "clusters": _clusters, "deep": _deep}
SPREADS = ("even", *_SPREADS)


# The light of the materials scenes: above the view and behind the camera,
# large enough for soft shadows; a little brighter than white, as the
# ambient light adds to it.
MIXED_LIGHT = lighting.Light(position=(-8.0, 14.0, -6.0), color=(1.0, 0.97, 0.9), intensity=1.0, radius=1.5)


def mixed_materials(n: int, seed: int = 0) -> list:
    """n materials, drawn from their own stream of the seed (the spheres'
    geometry is the seed's as without materials): half plastic (diffuse
    with a Phong highlight), a quarter mirrors, a quarter glass."""
    rng = np.random.default_rng([seed, 1])
    kind = rng.uniform(0.0, 1.0, n)
    specular = rng.uniform(0.2, 0.8, n)
    shininess = rng.uniform(8.0, 128.0, n)
    reflect = rng.uniform(0.5, 0.95, n)
    out = []
    for k, sp, sh, re in zip(kind, specular, shininess, reflect):
        if k < 0.5:
            out.append(lighting.Material(specular=float(sp), shininess=float(sh)))
        elif k < 0.75:
            out.append(lighting.Material(specular=0.5, shininess=64.0, reflect=float(re)))
        else:
            out.append(lighting.Material(specular=0.5, shininess=128.0, reflect=0.05, transmit=0.9, ior=1.5))
    return out
