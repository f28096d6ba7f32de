"""POV-Ray 3.7 scene files of raybench scenes: the same picture from POV-Ray,
for timing it beside raybench (benchmarks/peers.py) and for comparing the two.

text(scene, width, height, depth) writes the spheres, the meshes (one
mesh2 each), the lights, the materials, the background and the camera;
from_nff(nff, ...) an NFF's scene, its cones as POV-Ray's own; so that

    povray +Iscene.pov +W1680 +H1050 -A +WT2 File_Gamma=1.0

renders what raybench's Whitted shading renders at that size: the header of
the file gives the command. How each part is said (docs/reference/pov.md):

- the camera: raybench's eye, look-at point and up (POV-Ray's `sky`);
  raybench's fov_deg is the vertical field of view, POV-Ray's `angle` the
  horizontal one, so the angle written is 2 atan(tan(fov / 2) * width /
  height); raybench's coordinates are right-handed and POV-Ray's
  left-handed, so `right` points along -x, the usual way to say so;
- a material: the colour lit by what is left of it, keep = 1 - reflect -
  transmit, as raybench lights it: ambient keep * the scene's ambient,
  diffuse keep, Phong's highlight (`phong` specular, `phong_size`
  shininess, as raybench's glint: the light's mirror direction against the
  viewer's), `reflection` the mirrored share; a transmitting material's
  share as the pigment's `transmit` with its index of refraction, without
  raybench's Fresnel split (POV-Ray's own model: an approximation);
- lights: point lights of colour times intensity, no fall-off, shadows
  on (POV-Ray's default); an area light's radius is left out (its centre
  is the point light: POV-Ray's area lights are rectangles, not balls);
- depth: raybench's bounces; POV-Ray counts the primary ray as a level, so
  max_trace_level is depth + 1; adc_bailout is raybench's budget of
  dropped light, half a byte's step;
- the background: the scene's colour; the thesis's gradient (a scene with
  none) has no POV-Ray twin and is written black;
- colours are linear, as raybench writes its bytes: assumed_gamma 1, and
  the command's File_Gamma=1.0 keeps POV-Ray from encoding them as sRGB.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .. import lighting
from ..camera import Camera
from ..files import write_atomic
from ..scene import Scene

# raybench's budget of light a pixel may drop (kernels/whitted.py's CUTOFF).
BAILOUT = 0.5 / 255.0


def horizontal_angle(fov_deg: float, width: int, height: int) -> float:
    """POV-Ray's `angle` (horizontal, degrees) for raybench's vertical fov at width x height."""
    return math.degrees(2.0 * math.atan(math.tan(math.radians(fov_deg) / 2.0) * width / height))


def command(path, width: int, height: int, threads: int | None = None) -> list[str]:
    """The povray command that renders path at width x height as raybench does: no
    antialiasing, linear output, a PNG beside it; threads: POV-Ray's +WT."""
    args = ["povray", f"+I{path}", f"+W{width}", f"+H{height}", "-A", "File_Gamma=1.0", "+FN", "-D"]
    return args + ([f"+WT{threads}"] if threads else [])


def _v(values) -> str:
    return "<" + ", ".join(_n(x) for x in values) + ">"


def _n(x) -> str:
    return f"{float(x):.9g}"


def _texture(colour, material: lighting.Material, ambient) -> str:
    # POV-Ray lights a transmitting surface by 1 - transmit of itself: its light made up for it
    opaque = 1.0 - material.transmit
    keep = (1.0 - material.reflect - material.transmit) / opaque if opaque > 0 else 0.0
    pigment = f"rgb {_v(colour)}" + (f" transmit {_n(material.transmit)}" if material.transmit > 0 else "")
    finish = [f"ambient rgb {_v(np.asarray(ambient) * keep)}", f"diffuse {_n(keep)}"]
    if material.specular > 0:
        finish.append(f"phong {_n(material.specular)} phong_size {_n(material.shininess)}")
    if material.reflect > 0:
        finish.append(f"reflection {{ rgb {_n(material.reflect)} }}")
    interior = f" interior {{ ior {_n(material.ior)} }}" if material.transmit > 0 else ""
    return f"texture {{ pigment {{ {pigment} }} finish {{ {' '.join(finish)} }} }}{interior}"


def _looks(scene: Scene) -> tuple[list, np.ndarray]:
    """The spheres' distinct (colour, material) pairs and each sphere's index among them."""
    colours = scene.colors.astype(np.float64)
    materials = scene.materials or [lighting.MATTE] * len(scene)
    keys, which, seen = [], np.empty(len(scene), np.int64), {}
    for i, (colour, material) in enumerate(zip(map(tuple, colours.tolist()), materials)):
        key = (colour, material)
        if key not in seen:
            seen[key] = len(keys)
            keys.append(key)
        which[i] = seen[key]
    return keys, which


def text(scene: Scene, width: int, height: int, depth: int = lighting.DEFAULT_DEPTH, cones=None,
         camera: Camera | None = None, name: str = "FILE.pov") -> str:  # fmt: skip
    """The .pov text of scene (its spheres and meshes; cones, an NFF's, as
    POV-Ray's own cones) seen by camera (default the scene's, else Camera())
    at width x height, Whitted shading to depth bounces; name: the file's,
    in the command its first lines give."""
    depth = lighting.check_depth(depth)
    camera = camera or scene.camera or Camera()
    out = [
        "// raybench's scene for POV-Ray 3.7 (raybench.formats.pov); render it with",
        "// " + " ".join(command(name, width, height)),
        "#version 3.7;",
        f"global_settings {{ assumed_gamma 1.0 ambient_light rgb 1 max_trace_level {depth + 1} "
        f"adc_bailout {_n(BAILOUT)} }}",
        f"background {{ rgb {_v(scene.background or (0.0, 0.0, 0.0))} }}",
        "camera {",
        "  perspective",
        f"  location {_v(camera.position)}",
        f"  right <{_n(-width / height)}, 0, 0>",
        "  up <0, 1, 0>",
        f"  sky {_v(camera.up)}",
        f"  angle {_n(horizontal_angle(camera.fov_deg, width, height))}",
        f"  look_at {_v(camera.look_at)}",
        "}",
    ]
    for light in scene.lights:
        out.append(f"light_source {{ {_v(light.position)} color rgb {_v(np.asarray(light.color) * light.intensity)} }}")
    looks, which = _looks(scene)
    worn = []  # each look as the spheres wear it: its texture, and its interior (an object's, not a texture's)
    for k, (colour, material) in enumerate(looks):
        texture, _, interior = _texture(colour, material, scene.ambient).partition(" interior ")
        out.append(f"#declare T{k} = {texture}")
        if interior:
            out.append(f"#declare I{k} = interior {interior}")
        worn.append(f"texture {{ T{k} }}" + (f" interior {{ I{k} }}" if interior else ""))
    centres, radii = scene.centers, scene.radii
    out += [f"sphere {{ {_v(c)}, {_n(r)} {worn[k]} }}" for c, r, k in zip(centres, radii, which.tolist())]
    for mesh in scene.meshes:
        out += _mesh2(mesh, scene.ambient)
    if cones is not None:
        out += _cones(*cones, scene.ambient)
    return "\n".join(out) + "\n"


def _mesh2(placed, ambient) -> list[str]:
    """A scene's mesh (scene_meshes.SceneMesh) as one mesh2, with its normals where it has them."""
    mesh = placed.mesh
    out = ["mesh2 {", f"  vertex_vectors {{ {len(mesh.vertices)}, " + ", ".join(map(_v, mesh.vertices)) + " }"]
    if mesh.normals is not None:
        out.append(f"  normal_vectors {{ {len(mesh.normals)}, " + ", ".join(map(_v, mesh.normals)) + " }")
    faces = ", ".join(f"<{a}, {b}, {c}>" for a, b, c in mesh.faces.tolist())
    out.append(f"  face_indices {{ {len(mesh.faces)}, {faces} }}")
    out.append(f"  {_texture(placed.colour, placed.material, ambient)}")
    out.append("}")
    return out


def _cones(rows, looks, ambient) -> list[str]:
    """NFF's cones (K, 8 rows: base, its radius, apex, its radius) as POV-Ray's
    open cones (no caps, as NFF's), each with its (colour, Material)."""
    out = []
    for r, (colour, material) in zip(np.asarray(rows, np.float64).tolist(), looks):
        out.append(f"cone {{ {_v(r[:3])}, {_n(abs(r[3]))}, {_v(r[4:7])}, {_n(abs(r[7]))} open "
                   f"{_texture(colour, material, ambient)} }}")  # fmt: skip
    return out


def from_nff(nff, width: int, height: int, depth: int = lighting.DEFAULT_DEPTH, name: str = "FILE.pov") -> str:
    """The .pov text of an NFF: its spheres, polygons and patches as raybench
    draws them, and its cones as POV-Ray's own (raybench tessellates them:
    formats.polygons), the peer's best form of the same scene."""
    from .nff import WHITE

    scene = replace(nff, cones=np.zeros((0, 8)), cone_fill=np.zeros(0, np.int32)).scene()
    fills = [f.material() for f in (nff.fills or [WHITE])]
    cones = (nff.cones, [fills[i] for i in nff.cone_fill.tolist()]) if len(nff.cones) else None
    return text(scene, width, height, depth, cones, camera=scene.camera, name=name)


def save(path, pov_text: str) -> None:
    write_atomic(path, pov_text.encode())
