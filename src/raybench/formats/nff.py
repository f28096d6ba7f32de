"""Eric Haines's Neutral File Format (NFF, the SPD's output), read and written.

The format (Haines, "Neutral File Format", version 3.9, NFF.TXT in
erich666/StandardProceduralDatabases) is one entity a line, its first word
the kind: `v` (the view, six keyword lines), `b` (background), `l` (a
light), `f` (the fill: colour and shading of what follows), `s` (a sphere),
`p` and `pp` (a polygon and a polygon patch, with their vertex lines), `c`
(a cone or cylinder, two lines), and `#` comments.

read(text) / load(path) give an NFF: every entity as the file gives it.
NFF.scene() is the raybench Scene of its spheres, polygons, patches and
cones (the last three as triangles, formats.polygons), lights, camera and
background, with the fills mapped to raybench's materials
(docs/reference/nff.md gives the mapping and the reading of `angle`).
from_scene(scene) and NFF.text() write one. A malformed file is one
RaybenchError naming the file and the line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import lighting
from ..camera import MAX_MAGNITUDE, Camera
from ..errors import RaybenchError
from ..files import read_text, write_atomic
from ..scene import Scene

# An NFF of SPD balls at size 6 is about 30 MB; a text 30 times that is
# still read, one past it is refused before it is read.
MAX_NFF_BYTES = 2**30
# The view's keyword lines, in the order NFF.TXT writes them.
VIEW_KEYS = ("from", "at", "up", "angle", "hither", "resolution")
# The SPD's resolution, written where a scene gives none (NFF's `v` needs one).
SPD_RESOLUTION = (512, 512)


@dataclass(frozen=True)
class View:
    """NFF's `v`: eye, look-at point, up vector, angle (degrees), hither
    distance, resolution (x, y)."""

    position: tuple
    look_at: tuple
    up: tuple
    angle: float
    hither: float = 1.0
    resolution: tuple = SPD_RESOLUTION

    def camera(self) -> Camera:
        """NFF's angle is raybench's fov_deg: the full vertical field of view,
        edge to edge (docs/reference/nff.md#the-view-angle)."""
        return Camera(position=self.position, look_at=self.look_at, up=self.up, fov_deg=self.angle)


@dataclass(frozen=True)
class Fill:
    """NFF's `f`: colour, Kd, Ks, Shine (Phong's exponent), T (the
    transmitted share) and the index of refraction, as the file gives them."""

    color: tuple
    kd: float = 1.0
    ks: float = 0.0
    shine: float = 0.0
    t: float = 0.0
    ior: float = 1.0

    def material(self) -> tuple[tuple, lighting.Material]:
        """(diffuse colour, Material) under raybench's Whitted shading.

        Ks is both Phong's weight and the mirrored share, as in the MTV ray
        tracer that NFF was written for (the SPD's statistics count
        reflection rays exactly where Ks > 0); T the transmitted share. Where
        Ks + T > 1 both are scaled to sum to 1. raybench lights a hit's
        colour by what is left, 1 - Ks - T, so the colour is rgb * Kd / (1 -
        Ks - T), clipped to 1, to keep NFF's diffuse weight Kd * rgb (rgb as
        given where nothing is left). Shine is clipped to raybench's largest
        exponent; an index of refraction outside raybench's range is clipped
        where T > 0, and is 1 where nothing is transmitted."""
        ks, t = min(max(self.ks, 0.0), 1.0), min(max(self.t, 0.0), 1.0)
        if ks + t > 1.0:
            ks, t = ks / (ks + t), t / (ks + t)
        keep = 1.0 - ks - t
        rgb = np.asarray(self.color, np.float64)
        colour = rgb * (max(self.kd, 0.0) / keep) if keep > 0.0 else rgb
        colour = tuple(float(c) for c in np.clip(colour, 0.0, 1.0))
        if t > 0.0:
            ior = min(max(self.ior, lighting.MIN_IOR), lighting.MAX_IOR)
        else:
            ior = self.ior if lighting.MIN_IOR <= self.ior <= lighting.MAX_IOR else 1.0
        shininess = min(max(self.shine, 0.0), lighting.MAX_SHININESS)
        material = lighting.Material(specular=ks, shininess=shininess, reflect=ks, transmit=t, ior=ior)
        return colour, material

    @classmethod
    def of(cls, colour, material: lighting.Material) -> Fill:
        """The fill that material() maps back to (colour, material), where
        material.specular == material.reflect; NFF has one Ks for both, and
        the mirrored share is the one kept."""
        keep = 1.0 - material.reflect - material.transmit
        return cls(tuple(float(c) for c in colour), keep, material.reflect, material.shininess, material.transmit,
                   material.ior)  # fmt: skip


WHITE = Fill((1.0, 1.0, 1.0))  # what an object before any `f` is drawn with


@dataclass
class Polygon:
    """NFF's `p` (normals None) or `pp`: vertices (k, 3), counter-clockwise
    seen from the front; normals (k, 3) for a patch; the index of its fill."""

    vertices: np.ndarray
    normals: np.ndarray | None
    fill: int


@dataclass
class NFF:
    """Everything an NFF file holds, as it holds it: spheres (N, 4) x, y, z,
    radius and sphere_fill (N,); polygons (p and pp); cones (K, 8): base x,
    y, z, radius, apex x, y, z, radius, and cone_fill (K,); fills (each an
    index of the entities' fill); lights, each (position, rgb or None)."""

    view: View | None = None
    background: tuple | None = None
    lights: list = field(default_factory=list)
    fills: list = field(default_factory=list)
    spheres: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    sphere_fill: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    polygons: list = field(default_factory=list)
    cones: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    cone_fill: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    # spheres read with a negative radius (NFF: only the inside is visible),
    # which raybench draws as ordinary spheres
    inside_out: int = 0

    def counts(self) -> dict:
        """The primitives by kind: spheres, polygons, patches, cones."""
        patches = sum(p.normals is not None for p in self.polygons)
        return {"spheres": len(self.spheres), "polygons": len(self.polygons) - patches, "patches": patches,
                "cones": len(self.cones)}  # fmt: skip

    def scene(self) -> Scene:
        """The raybench Scene: its spheres, and its polygons, patches and
        cones as meshes of triangles (polygons.meshes), with the lights,
        camera and background, the fills mapped by Fill.material; a file
        without `v` gets a camera fitted to everything in it. Lights have no
        intensity in NFF: each gets Haines's relative intensity
        sqrt(L) / (2 L) for L lights, and the ambient light the same grey
        (the SPD's README, "Since the SPD package is designed to test
        efficiency")."""
        from . import polygons

        looks = [f.material() for f in (self.fills or [WHITE])]
        table = np.array([c for c, _ in looks], np.float64).reshape(-1, 3)
        which = self.sphere_fill
        colours = table[which] if len(which) else np.zeros((0, 3))
        materials = [looks[i][1] for i in which.tolist()]
        meshes = polygons.meshes(self, looks)
        share = relative_intensity(len(self.lights))
        lights = [_light(position, rgb, share) for position, rgb in self.lights]
        camera = self.view.camera() if self.view is not None else None
        if camera is None and (len(self.spheres) or meshes):
            from . import fit_camera

            corners = [m.mesh.vertices for m in meshes]
            centers = np.concatenate([self.spheres[:, :3], *corners])
            radii = np.concatenate([np.abs(self.spheres[:, 3]), np.zeros(sum(map(len, corners)))])
            camera = fit_camera(centers, radii)
        background = (0.0, 0.0, 0.0) if self.background is None else self.background  # NFF's default
        return Scene(self.spheres[:, :3], np.abs(self.spheres[:, 3]), colours, camera, materials=materials,
                     lights=lights, ambient=(share,) * 3, background=background, meshes=meshes)  # fmt: skip

    def triangles(self):
        """The polygons' and patches' fans of triangles, then the cones' (polygons.triangles)."""
        from . import polygons

        return polygons.triangles(self)

    def notes(self) -> list[str]:
        """One line for what raybench draws other than the file says, [] where nothing."""
        notes = []
        if self.inside_out:
            notes.append(
                f"note: {self.inside_out:,} spheres have a negative radius (NFF: only the inside is visible); "
                "they are drawn as ordinary spheres"
            )
        return notes

    def text(self) -> str:
        """The NFF text: view, background, lights, then the spheres,
        polygons and cones, each run of one fill after its `f` line. Scalars
        are written in Python's shortest form (they read back exactly);
        geometry with 9 significant digits, which float32 reads back exactly."""
        out = []
        if self.view is not None:
            v = self.view
            out += ["v", "from " + _nums(v.position), "at " + _nums(v.look_at), "up " + _nums(v.up),
                    f"angle {_num(v.angle)}", f"hither {_num(v.hither)}",
                    f"resolution {int(v.resolution[0])} {int(v.resolution[1])}"]  # fmt: skip
        if self.background is not None:
            out.append("b " + _nums(self.background))
        for position, rgb in self.lights:
            out.append("l " + _nums(position) + ("" if rgb is None else " " + _nums(rgb)))
        current = [-1]

        def fill(i):
            if i != current[0]:
                f = self.fills[i] if self.fills else WHITE
                out.append("f " + _nums((*f.color, f.kd, f.ks, f.shine, f.t, f.ior)))
                current[0] = i

        for i, rows in _runs(self.sphere_fill, self.spheres):
            fill(i)
            out.append("\n".join("s " + _row(r) for r in rows.tolist()))
        for poly in self.polygons:
            fill(poly.fill)
            if poly.normals is None:
                out.append(f"p {len(poly.vertices)}")
                out += [_row(r) for r in poly.vertices.tolist()]
            else:
                out.append(f"pp {len(poly.vertices)}")
                rows = np.concatenate([poly.vertices, poly.normals], axis=1).tolist()
                out += [_row(r) for r in rows]
        for i, rows in _runs(self.cone_fill, self.cones):
            fill(i)
            for r in rows.tolist():
                out += ["c", _row(r[:4]), _row(r[4:])]
        return "\n".join(out) + "\n"

    def save(self, path) -> None:
        write_atomic(path, self.text().encode())


SINGULAR = {"spheres": "sphere", "polygons": "polygon", "patches": "patch", "cones": "cone"}


def counted(n: int, kind: str) -> str:
    """'1 polygon', '7,381 spheres': a count of a kind of primitive (counts()'s keys)."""
    return f"{n:,} {SINGULAR[kind] if n == 1 else kind}"


def relative_intensity(lights: int) -> float:
    """Haines's intensity of each of `lights` lights and of the ambient light."""
    return math.sqrt(lights) / (2 * lights) if lights else 0.5


def _light(position, rgb, share: float) -> lighting.Light:
    """An NFF light as a raybench Light: its colour (white where the file
    gives none) times share; a colour over 1 moves into the intensity."""
    rgb = (1.0, 1.0, 1.0) if rgb is None else rgb
    top = max(rgb)
    if top > 1.0:
        return lighting.Light(position, tuple(c / top for c in rgb), share * top)
    return lighting.Light(position, rgb, share)


def _runs(which: np.ndarray, rows: np.ndarray):
    """(fill, its rows) for each run of one fill, in order."""
    if not len(which):
        return
    edges = np.flatnonzero(np.diff(which)) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [len(which)]])
    for a, b in zip(starts.tolist(), stops.tolist()):
        yield int(which[a]), rows[a:b]


def _row(values) -> str:
    """Geometry: 9 significant digits, which read back as float32 exactly."""
    return " ".join(f"{v:.9g}" for v in values)


def _num(x) -> str:
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def _nums(values) -> str:
    return " ".join(_num(x) for x in values)


def from_scene(scene: Scene, resolution=SPD_RESOLUTION) -> NFF:
    """The NFF of a raybench Scene: its spheres, each mesh's triangles as
    polygons of three vertices (patches, `pp`, where the mesh has vertex
    normals), camera (a fitted one where the scene has none), background (black for the thesis's gradient, which NFF
    cannot say), lights (colour times intensity over Haines's relative
    intensity, so that reading it back gives the same light; an area light's
    radius is dropped), a fill per distinct (colour, material) by Fill.of."""
    from . import fit_camera

    camera = scene.camera
    if camera is None:
        corners = [m.mesh.vertices.astype(np.float64) for m in scene.meshes]
        centers = np.concatenate([scene.centers.astype(np.float64), *corners])
        radii = np.concatenate([scene.radii.astype(np.float64), np.zeros(len(centers) - len(scene))])
        camera = fit_camera(centers, radii) if len(centers) else Camera()
    view = View(camera.position, camera.look_at, camera.up, camera.fov_deg, 1.0, tuple(resolution))
    share = relative_intensity(len(scene.lights))
    lights = [(light.position, tuple(c * light.intensity / share for c in light.color)) for light in scene.lights]
    n = len(scene)
    materials = scene.materials or (lighting.MATTE,) * n
    fills, index, which = [], {}, np.empty(n, np.int32)
    for i, (colour, material) in enumerate(zip(scene.colors.tolist(), materials)):
        key = (tuple(colour), material)
        if key not in index:
            index[key] = len(fills)
            fills.append(Fill.of(colour, material))
        which[i] = index[key]
    spheres = np.concatenate([scene.centers, scene.radii[:, None]], axis=1).astype(np.float64)
    polygons = []
    for placed in scene.meshes:
        key = (tuple(placed.colour), placed.material)
        if key not in index:
            index[key] = len(fills)
            fills.append(Fill.of(*key))
        mesh = placed.mesh
        corners = mesh.vertices[mesh.faces].astype(np.float64)
        normals = None if mesh.normals is None else mesh.normals[mesh.faces].astype(np.float64)
        for k in range(len(corners)):
            polygons.append(Polygon(corners[k], None if normals is None else normals[k], index[key]))
    return NFF(view=view, background=scene.background or (0.0, 0.0, 0.0), lights=lights, fills=fills,
               spheres=spheres, sphere_fill=which, polygons=polygons)  # fmt: skip


def load(path) -> NFF:
    path = Path(path)
    return read(read_text(path, "NFF file", MAX_NFF_BYTES), str(path))


def load_view(path) -> View | None:
    """The view of an NFF file, or None where it has none: read up to it
    only (NFF.TXT puts it before any object), for its resolution."""
    path = Path(path)
    reader = _Reader(read_text(path, "NFF file", MAX_NFF_BYTES), str(path))
    while (words := reader.next()) is not None:
        if words[0] == "v":
            reader.view(words[1:])
            return reader.nff.view
    return None


def read(text: str, name: str = "NFF") -> NFF:
    """The NFF in text; a malformed line is one RaybenchError, "name: line N: why"."""
    return _Reader(text, name).read()


class _Reader:
    """One pass over the lines; `#` starts a comment anywhere on a line."""

    def __init__(self, text: str, name: str):
        self.lines = text.splitlines()
        self.name = name
        self.i = 0  # the index of the next line
        self.nff = NFF()
        self.spheres, self.sphere_fill, self.cones, self.cone_fill = [], [], [], []
        self.fill = -1  # no `f` yet

    def fail(self, why: str, line: int | None = None):
        raise RaybenchError(f"{self.name}: line {self.i if line is None else line}: {why}")

    def next(self) -> list[str] | None:
        """The next line's words that is not blank or a comment, or None at the end."""
        while self.i < len(self.lines):
            line = self.lines[self.i]
            self.i += 1
            cut = line.find("#")
            words = (line if cut < 0 else line[:cut]).split()
            if words:
                return words
        return None

    def numbers(self, words, count, what: str) -> list[float]:
        """count finite numbers, at most MAX_MAGNITUDE each; counts may be a tuple of allowed counts."""
        allowed = count if isinstance(count, tuple) else (count,)
        if len(words) not in allowed:
            want = " or ".join(str(c) for c in allowed)
            self.fail(f"{what}: expected {want} numbers, got {len(words)}")
        try:
            values = [float(w) for w in words]
        except ValueError:
            bad = next(w for w in words if not _is_float(w))
            self.fail(f"{what}: {bad[:40]!r} is not a number")
        for v in values:
            if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
                self.fail(f"{what}: {v:g} is not finite or over {MAX_MAGNITUDE:g} in magnitude")
        return values

    def fill_index(self) -> int:
        if self.fill < 0:  # geometry before any `f`: NFF.TXT names no default
            self.nff.fills.append(WHITE)
            self.fill = len(self.nff.fills) - 1
        return self.fill

    def read(self) -> NFF:
        nff = self.nff
        while (words := self.next()) is not None:
            kind, rest = words[0], words[1:]
            if kind == "s":
                x, y, z, r = self.numbers(rest, 4, "s (sphere: x y z radius)")
                if r == 0:
                    self.fail("s: a sphere's radius must not be 0")
                nff.inside_out += r < 0
                self.spheres.append((x, y, z, r))
                self.sphere_fill.append(self.fill_index())
            elif kind in ("p", "pp"):
                self.polygon(kind, rest)
            elif kind == "f":
                values = self.numbers(rest, 8, "f (fill: r g b Kd Ks Shine T index_of_refraction)")
                if min(values[:3]) < 0:
                    self.fail("f: a colour's channels must be >= 0")
                nff.fills.append(Fill(tuple(values[:3]), *values[3:]))
                self.fill = len(nff.fills) - 1
            elif kind == "l":
                values = self.numbers(rest, (3, 6), "l (light: x y z [r g b])")
                if len(nff.lights) == lighting.MAX_LIGHTS:
                    self.fail(f"l: more than {lighting.MAX_LIGHTS} lights, raybench's most")
                if len(values) == 6 and min(values[3:]) < 0:
                    self.fail("l: a light's colour must be >= 0")
                nff.lights.append((tuple(values[:3]), tuple(values[3:]) if len(values) == 6 else None))
            elif kind == "b":
                values = self.numbers(rest, 3, "b (background: r g b)")
                if not all(0.0 <= v <= 1.0 for v in values):
                    self.fail("b: each channel must be in [0, 1]")
                nff.background = tuple(values)
            elif kind == "c":
                self.cone(rest)
            elif kind == "v":
                self.view(rest)
            else:
                self.fail(f"unknown entity {kind[:40]!r} (NFF has v, b, l, f, s, p, pp, c and # comments)")
        nff.spheres = np.array(self.spheres, np.float64).reshape(-1, 4)
        nff.sphere_fill = np.array(self.sphere_fill, np.int32)
        nff.cones = np.array(self.cones, np.float64).reshape(-1, 8)
        nff.cone_fill = np.array(self.cone_fill, np.int32)
        return nff

    def polygon(self, kind: str, rest):
        what = "p (polygon)" if kind == "p" else "pp (polygon patch)"
        start = self.i
        if len(rest) != 1 or not rest[0].isdigit():
            self.fail(f"{what}: expected the vertex count, one whole number")
        count = int(rest[0])
        if count < 3:
            self.fail(f"{what}: a polygon needs at least 3 vertices, got {count}")
        width = 3 if kind == "p" else 6
        rows = []
        for k in range(count):
            words = self.next()
            if words is None:
                self.fail(f"{what}: the file ends after {k} of its {count} vertices", start)
            rows.append(self.numbers(words, width, f"{what} vertex {k + 1}" + (" (x y z)" if width == 3 else
                                                                              " (x y z nx ny nz)")))  # fmt: skip
        rows = np.array(rows, np.float64)
        normals = rows[:, 3:] if kind == "pp" else None
        self.nff.polygons.append(Polygon(rows[:, :3], normals, self.fill_index()))

    def cone(self, rest):
        """NFF.TXT's `c` and its base and apex lines; or all eight numbers on
        the `c` line, as the SPD's own programs write it."""
        start = self.i
        if len(rest) == 8:
            self.cones.append(self.numbers(rest, 8, "c (cone: base x y z radius apex x y z radius)"))
            self.cone_fill.append(self.fill_index())
            return
        if rest:
            self.fail("c: expected nothing after c (its base and apex lines follow), or all 8 numbers")
        ends = []
        for what in ("base", "apex"):
            words = self.next()
            if words is None:
                self.fail(f"c: the file ends before the cone's {what} line", start)
            ends += self.numbers(words, 4, f"c (cone) {what}: x y z radius")
        self.cones.append(ends)
        self.cone_fill.append(self.fill_index())

    def view(self, rest):
        start = self.i
        if rest:
            self.fail("v: expected nothing after v (its keyword lines follow)")
        if self.nff.view is not None:
            self.fail("v: a second view (NFF has one)")
        got = {}
        while len(got) < len(VIEW_KEYS):
            mark = self.i
            words = self.next()
            if words is None or words[0] not in VIEW_KEYS:
                self.i = mark  # the next entity
                break
            key = words[0]
            if key in got:
                self.fail(f"v: a second {key!r} line")
            if key == "resolution":
                if len(words) != 3 or not all(w.isdigit() and int(w) > 0 for w in words[1:]):
                    self.fail("v: resolution: expected two whole numbers above 0 (x y)")
                got[key] = (int(words[1]), int(words[2]))
            else:
                count = 1 if key in ("angle", "hither") else 3
                values = self.numbers(words[1:], count, f"v: {key}")
                got[key] = values[0] if count == 1 else tuple(values)
        missing = [k for k in ("from", "at", "up", "angle") if k not in got]
        if missing:
            self.fail(f"v: no {missing[0]!r} line (a view has from, at, up, angle, hither, resolution)", start)
        view = View(got["from"], got["at"], got["up"], got["angle"], got.get("hither", 1.0),
                    got.get("resolution", SPD_RESOLUTION))  # fmt: skip
        try:
            view.camera()
        except RaybenchError as exc:
            self.fail(f"v: {exc}", start)
        self.nff.view = view


def _is_float(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True
