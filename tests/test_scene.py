"""Scene: JSON round trip, the random generator, and validation of bad input."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from raybench import Camera, RaybenchError, Scene, random_spheres
from raybench import scene as scene_module

TAN30 = math.tan(math.radians(30.0))
PLANE_H = 2.0 * TAN30
PLANE_W = PLANE_H * 4.0 / 3.0


def fresh_seed() -> int:
    """A new seed every run; tests put it in their assertion messages."""
    return int(np.random.SeedSequence().entropy % 2**63)


def random_camera(rng: np.random.Generator) -> Camera:
    position = rng.normal(size=3) * 10.0
    look_at = position + rng.normal(size=3)
    return Camera(
        position=tuple(position), look_at=tuple(look_at), up=(0.0, 1.0, 0.0), fov_deg=float(rng.uniform(10.0, 170.0))
    )


def only_files(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# --------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("n", [0, 1, 37])
@pytest.mark.parametrize("with_camera", [False, True], ids=["no-camera", "camera"])
@pytest.mark.parametrize("source", ["random_spheres", "raw-rng"])
def test_round_trip_is_bit_exact(tmp_path, n, with_camera, source):
    seed = fresh_seed()
    rng = np.random.default_rng(seed)
    camera = random_camera(rng) if with_camera else None
    if source == "random_spheres":
        base = random_spheres(n, int(rng.integers(0, 2**32)))
        scene = Scene(base.centers, base.radii, base.colors, camera)
    else:
        # Arbitrary float32 values with all mantissa bits in use.
        scene = Scene(rng.uniform(-1e3, 1e3, (n, 3)), rng.uniform(1e-3, 10.0, n), rng.uniform(0.0, 1.0, (n, 3)), camera)
    msg = f"seed={seed} n={n} camera={camera!r}"
    assert scene.spheres.dtype == np.float32 and scene.spheres.shape == (7, n), msg

    path = tmp_path / "scene.json"
    scene.save(path)
    assert only_files(tmp_path) == ["scene.json"], msg  # no temp file left behind
    loaded = Scene.load(path)
    assert loaded.spheres.dtype == np.float32, msg
    assert np.array_equal(loaded.spheres, scene.spheres), msg
    assert loaded.spheres.tobytes() == scene.spheres.tobytes(), msg
    assert loaded.camera == camera, msg
    assert len(loaded) == n, msg

    again = Scene.from_dict(scene.to_dict())
    assert np.array_equal(again.spheres, scene.spheres), msg
    assert again.spheres.tobytes() == scene.spheres.tobytes(), msg
    assert again.camera == camera, msg

    # And through JSON text in memory, as a user's tool would.
    via_text = Scene.from_dict(json.loads(json.dumps(scene.to_dict())))
    assert via_text.spheres.tobytes() == scene.spheres.tobytes(), msg
    assert via_text.camera == camera, msg


def test_save_overwrites_and_leaves_no_temp_file(tmp_path):
    path = tmp_path / "s.json"
    random_spheres(5, 1).save(path)
    random_spheres(3, 2).save(path)
    assert only_files(tmp_path) == ["s.json"]
    assert np.array_equal(Scene.load(path).spheres, random_spheres(3, 2).spheres)


# --------------------------------------------------------------------------- generator


def test_random_spheres_is_deterministic():
    a = random_spheres(100, 7)
    b = random_spheres(100, 7)
    c = random_spheres(100, 8)
    assert np.array_equal(a.spheres, b.spheres)
    assert not np.array_equal(a.spheres, c.spheres)
    assert random_spheres(100).spheres.tobytes() == random_spheres(100, 0).spheres.tobytes()
    assert a.camera is None


# The generator fills the view of a picture ASPECT wide (scene.py's constant;
# 4:3 before it had one), about COVERAGE times over.
ASPECT = getattr(scene_module, "ASPECT", 4.0 / 3.0)
COVERAGE = getattr(scene_module, "COVERAGE", 2.0)


@pytest.mark.parametrize("n,seed", [(10, 0), (10, 1), (1000, 0), (1000, 5), (100_000, 0)])
def test_random_spheres_lie_in_the_default_view(n, seed):
    scene = random_spheres(n, seed)
    assert len(scene) == n
    centers = scene.centers.astype(np.float64)
    x, y, z = centers.T
    # float32 rounding of x and z may move x/z by an ulp or so.
    slack = 1.0 + 1e-6
    assert (z > 0).all()
    assert (np.abs(x / z) <= TAN30 * ASPECT * slack).all(), (ASPECT, np.abs(x / z).max())
    assert (np.abs(y / z) <= TAN30 * slack).all(), np.abs(y / z).max()
    # Spread over the whole view, not bunched in the middle.
    if n >= 1000:
        assert np.abs(x / z).max() > 0.95 * TAN30 * ASPECT
        assert np.abs(y / z).max() > 0.95 * TAN30
    radii = scene.radii
    assert (radii > 0).all() and np.isfinite(radii).all()
    colors = scene.colors
    assert ((colors >= 0.0) & (colors <= 1.0)).all()
    # The camera at the origin is outside every sphere.
    distance = np.linalg.norm(centers, axis=1)
    assert (distance > radii.astype(np.float64)).all(), (distance / radii).min()


def coverage(scene: Scene, plane_w: float = PLANE_W, plane_h: float = PLANE_H) -> float:
    """Total projected solid angle of the spheres over the view area (4:3 by default)."""
    r = scene.radii.astype(np.float64)
    z = scene.centers[:, 2].astype(np.float64)
    return float(np.sum(np.pi * (r / z) ** 2) / (plane_w * plane_h))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_spheres_coverage_is_constant_in_n(seed):
    values = {n: coverage(random_spheres(n, seed)) for n in (10, 1000, 100_000)}
    for n, c in values.items():
        assert 1.0 <= c <= 4.0, f"n={n} seed={seed}: 4:3 coverage {c:.3f} (all: {values})"
    # Large n converge on COVERAGE x E[s^2] = COVERAGE x 13/12 for s ~ U(0.5, 1.5),
    # over the generator's own view area.
    own = coverage(random_spheres(100_000, seed), PLANE_H * ASPECT, PLANE_H)
    assert own == pytest.approx(COVERAGE * 13.0 / 12.0, rel=0.02), own


def test_random_spheres_zero_and_bad_arguments():
    assert len(random_spheres(0, 3)) == 0
    assert random_spheres(0).spheres.shape == (7, 0)
    for bad in (-1, 1.5, True, "10"):
        with pytest.raises(RaybenchError, match="sphere count"):
            random_spheres(bad)
    for bad in (-1, 1.5, True):
        with pytest.raises(RaybenchError, match="seed"):
            random_spheres(3, bad)


def occupied(scene: Scene, cells=(128, 80)) -> float:
    """The share of a grid of cells over the view that holds a sphere's centre."""
    x, y, z = scene.centers.astype(np.float64).T
    u = np.clip(((x / z) / (TAN30 * ASPECT) + 1) / 2 * cells[0], 0, cells[0] - 1).astype(int)
    v = np.clip(((y / z) / TAN30 + 1) / 2 * cells[1], 0, cells[1] - 1).astype(int)
    return len(set(zip(u.tolist(), v.tolist()))) / (cells[0] * cells[1])


@pytest.mark.parametrize("layout", [x for x in scene_module.SPREADS if x != "even"])
def test_denser_layouts(rng, layout):
    """Each layout: deterministic by seed, n spheres in front of the camera
    (none reaching it), and what its name says, measured against the even spread of the same n and seed."""
    n, seed = int(rng.integers(20_000, 60_000)), int(rng.integers(0, 2**32))
    scene = random_spheres(n, seed, layout=layout)
    even = random_spheres(n, seed)
    assert np.array_equal(scene.spheres, random_spheres(n, seed, layout=layout).spheres)
    assert not np.array_equal(scene.spheres, random_spheres(n, seed + 1, layout=layout).spheres)
    assert len(scene) == n
    centers, radii = scene.centers.astype(np.float64), scene.radii.astype(np.float64)
    assert (radii > 0).all() and (np.linalg.norm(centers, axis=1) > radii).all()
    z = centers[:, 2]
    if layout == "dense":  # spheres 3 times larger: 9 times the coverage
        assert coverage(scene) / coverage(even) == pytest.approx(9.0, rel=0.05)
    elif layout == "deep":  # three decades of depth, the even one's angular sizes
        assert z.min() < 1.05 and z.max() > 950 and np.median(z) == pytest.approx(np.sqrt(1000), rel=0.1)
        assert coverage(scene) == pytest.approx(coverage(even), rel=0.05)
    else:  # clusters: the centres in far fewer cells of the view than the even ones
        assert occupied(scene) < 0.8 * occupied(even)


def test_bad_layout_is_refused():
    for bad in ("Even", "", None, 3):
        with pytest.raises(RaybenchError, match="layout"):
            random_spheres(3, 0, layout=bad)


# --------------------------------------------------------------------------- bad input


def valid_doc() -> dict:
    return {
        "format": "raybench-scene",
        "version": 1,
        "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1], "up": [0, 1, 0], "fov_deg": 60},
        "spheres": [
            {"center": [0, 0, 5], "radius": 1, "color": [1, 0, 0]},
            {"center": [1, 1, 8], "radius": 0.5, "color": [0, 1, 0]},
            {"center": [-1, 0, 9], "radius": 2.0, "color": [0, 0, 1]},
        ],
    }


def test_valid_doc_is_valid(tmp_path):
    scene = Scene.from_dict(valid_doc())
    assert len(scene) == 3 and scene.camera == Camera()
    path = tmp_path / "ok.json"
    path.write_text(json.dumps(valid_doc()))
    assert np.array_equal(Scene.load(path).spheres, scene.spheres)


def _set(path, value):
    def mutate(doc):
        obj = doc
        for key in path[:-1]:
            obj = obj[key]
        obj[path[-1]] = value

    return mutate


def _del(path):
    def mutate(doc):
        obj = doc
        for key in path[:-1]:
            obj = obj[key]
        del obj[path[-1]]

    return mutate


S1 = ("spheres", 1)
BAD_DOCS = [
    ("missing-format", _del(("format",)), "format"),
    ("wrong-format", _set(("format",), "raybench-scene-v2"), "format"),
    ("format-null", _set(("format",), None), "format"),
    ("missing-version", _del(("version",)), "version"),
    ("wrong-version", _set(("version",), 4), "version"),
    ("version-string", _set(("version",), "1"), "version"),
    ("version-bool", _set(("version",), True), "version"),
    ("unknown-top-key", _set(("lights",), []), "lights"),
    ("missing-spheres", _del(("spheres",)), "spheres"),
    ("spheres-not-list", _set(("spheres",), {"center": [0, 0, 5]}), "spheres"),
    ("sphere-not-object", _set(S1, [0, 0, 5]), "spheres[1]"),
    ("unknown-sphere-key", _set(S1 + ("colour",), [1, 1, 1]), "spheres[1].colour"),
    ("missing-radius", _del(S1 + ("radius",)), "spheres[1].radius"),
    ("missing-center", _del(S1 + ("center",)), "spheres[1].center"),
    ("missing-color", _del(S1 + ("color",)), "spheres[1].color"),
    ("radius-0", _set(S1 + ("radius",), 0), "spheres[1].radius"),
    ("radius-negative", _set(S1 + ("radius",), -0.5), "spheres[1].radius"),
    ("radius-bool", _set(S1 + ("radius",), True), "spheres[1].radius"),
    ("radius-string", _set(S1 + ("radius",), "1"), "spheres[1].radius"),
    ("radius-list", _set(S1 + ("radius",), [1]), "spheres[1].radius"),
    ("radius-huge", _set(S1 + ("radius",), 1e20), "spheres[1].radius"),
    ("center-huge", _set(S1 + ("center",), [0, 1e20, 5]), "spheres[1].center"),
    ("center-string", _set(S1 + ("center",), "0, 0, 5"), "spheres[1].center"),
    ("center-2-items", _set(S1 + ("center",), [0, 5]), "spheres[1].center"),
    ("center-bool-item", _set(S1 + ("center",), [0, False, 5]), "spheres[1].center"),
    ("center-null-item", _set(S1 + ("center",), [0, None, 5]), "spheres[1].center"),
    ("color-1.5", _set(S1 + ("color",), [0.5, 1.5, 0.5]), "spheres[1].color"),
    ("color-negative", _set(S1 + ("color",), [0.5, 0.5, -0.1]), "spheres[1].color"),
    ("color-2-items", _set(S1 + ("color",), [0.5, 0.5]), "spheres[1].color"),
    ("camera-not-object", _set(("camera",), [0, 0, 0]), "camera"),
    ("camera-unknown-key", _set(("camera", "zoom"), 2), "camera.zoom"),
    ("camera-fov-0", _set(("camera", "fov_deg"), 0), "camera.fov_deg"),
    ("camera-fov-180", _set(("camera", "fov_deg"), 180), "camera.fov_deg"),
    ("camera-fov-negative", _set(("camera", "fov_deg"), -30), "camera.fov_deg"),
    ("camera-fov-bool", _set(("camera", "fov_deg"), True), "camera.fov_deg"),
    ("camera-position-2-items", _set(("camera", "position"), [0, 0]), "camera.position"),
    ("camera-look_at-equals-position", _set(("camera", "look_at"), [0, 0, 0]), "camera.look_at"),
    ("camera-up-parallel", _set(("camera", "up"), [0, 0, 3]), "camera.up"),
    ("camera-up-antiparallel", _set(("camera", "up"), [0, 0, -1]), "camera.up"),
    ("camera-up-zero", _set(("camera", "up"), [0, 0, 0]), "camera.up"),
]


@pytest.mark.parametrize("mutate,where", [pytest.param(m, w, id=i) for i, m, w in BAD_DOCS])
def test_bad_doc_names_the_field(mutate, where, tmp_path):
    doc = copy.deepcopy(valid_doc())
    mutate(doc)
    with pytest.raises(RaybenchError) as info:
        Scene.from_dict(doc)
    message = str(info.value)
    assert message.startswith(where + ":"), message
    assert "\n" not in message

    # The same document from a file: the message adds the file, keeps the field.
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(RaybenchError) as info:
        Scene.load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {where}:"), message
    assert "\n" not in message


@pytest.mark.parametrize("doc", [None, [], "raybench-scene", 1], ids=repr)
def test_doc_not_an_object(doc):
    with pytest.raises(RaybenchError, match="scene: must be a JSON object"):
        Scene.from_dict(doc)


@pytest.mark.parametrize("text", ["{", "", "{'format': 'raybench-scene'}", '{"format": "raybench-scene",}', "nul"])
def test_malformed_json_file(tmp_path, text):
    path = tmp_path / "broken.json"
    path.write_text(text)
    with pytest.raises(RaybenchError) as info:
        Scene.load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: not valid JSON"), message
    assert "line 1" in message


def test_missing_and_unreadable_scene_file(tmp_path):
    with pytest.raises(RaybenchError, match="no such scene file") as info:
        Scene.load(tmp_path / "nope.json")
    assert "nope.json" in str(info.value)
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(RaybenchError, match="cannot read the scene file") as info:
        Scene.load(binary)
    assert "binary.json" in str(info.value)
    with pytest.raises(RaybenchError, match="cannot read the scene file"):
        Scene.load(tmp_path)  # a folder


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_json_nan_literals_are_refused(tmp_path, literal):
    # Python's json module accepts these non-standard literals; the loader must not.
    text = json.dumps(valid_doc()).replace('"radius": 0.5', f'"radius": {literal}')
    assert literal in text
    path = tmp_path / "nan.json"
    path.write_text(text)
    with pytest.raises(RaybenchError) as info:
        Scene.load(path)
    assert f"spheres[1].radius: must be a finite number, got {literal}" in str(info.value)


def three_spheres():
    centers = np.array([[0, 0, 5], [1, 1, 8], [-1, 0, 9]], dtype=np.float64)
    radii = np.array([1.0, 0.5, 2.0])
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    return centers, radii, colors


@pytest.mark.parametrize(
    "field,column,value,where",
    [
        ("centers", 0, np.nan, "spheres[1].center"),
        ("centers", 2, np.inf, "spheres[1].center"),
        ("centers", 1, -np.inf, "spheres[1].center"),
        ("centers", 1, 1e20, "spheres[1].center"),
        ("centers", 0, -1e20, "spheres[1].center"),
        ("radii", None, np.nan, "spheres[1].radius"),
        ("radii", None, np.inf, "spheres[1].radius"),
        ("radii", None, -np.inf, "spheres[1].radius"),
        ("radii", None, 1e20, "spheres[1].radius"),
        ("radii", None, 0.0, "spheres[1].radius"),
        ("radii", None, -1.0, "spheres[1].radius"),
        ("colors", 0, np.nan, "spheres[1].color"),
        ("colors", 1, np.inf, "spheres[1].color"),
        ("colors", 2, 1.5, "spheres[1].color"),
        ("colors", 0, -0.1, "spheres[1].color"),
    ],
)
def test_constructor_refuses_non_finite_and_out_of_range(field, column, value, where):
    arrays = dict(zip(("centers", "radii", "colors"), three_spheres()))
    if column is None:
        arrays[field][1] = value
    else:
        arrays[field][1, column] = value
    with pytest.raises(RaybenchError) as info:
        Scene(arrays["centers"], arrays["radii"], arrays["colors"])
    assert str(info.value).startswith(where + ":"), str(info.value)


@pytest.mark.parametrize("odd", [0, 1, 2])
@pytest.mark.parametrize("count", [2, 4])
def test_constructor_refuses_mismatched_counts(odd, count):
    """Any one of the three arrays shorter or longer than the others: one
    line naming the counts (not a NumPy error from joining them)."""
    arrays = list(three_spheres())
    arrays[odd] = np.resize(arrays[odd], (count, *arrays[odd].shape[1:]))
    counts = [3, 3, 3]
    counts[odd] = count
    want = f"{counts[0]} centers, {counts[1]} radii and {counts[2]} colors"
    with pytest.raises(RaybenchError, match=want):
        Scene(*arrays)


@pytest.mark.parametrize(
    "kwargs,where",
    [
        (dict(fov_deg=0), "camera.fov_deg"),
        (dict(fov_deg=180), "camera.fov_deg"),
        (dict(fov_deg=float("nan")), "camera.fov_deg"),
        (dict(fov_deg="wide"), "camera.fov_deg"),
        (dict(position=(1, 2, 3), look_at=(1, 2, 3)), "camera.look_at"),
        (dict(up=(0, 0, 1)), "camera.up"),
        (dict(position=(0, 0, 0), look_at=(2, 2, 2), up=(-1, -1, -1)), "camera.up"),
        (dict(position=(0, float("inf"), 0)), "camera.position"),
        (dict(look_at=(0, 1)), "camera.look_at"),
        (dict(up="up"), "camera.up"),
    ],
)
def test_camera_refuses_bad_values(kwargs, where):
    with pytest.raises(RaybenchError) as info:
        Camera(**kwargs)
    assert str(info.value).startswith(where + ":"), str(info.value)


# --------------------------------------------------------------------------- found bugs, fixed


def test_huge_json_integer_is_a_raybench_error():
    doc = valid_doc()
    doc["spheres"][1]["radius"] = 10**400
    with pytest.raises(RaybenchError, match=r"^spheres\[1\]\.radius:"):
        Scene.from_dict(doc)


def test_radius_that_underflows_float32_is_refused():
    try:
        scene = Scene([[0, 0, 5]], [1e-46], [[1, 1, 1]])
    except RaybenchError as exc:
        assert str(exc).startswith("spheres[0].radius:")
    else:
        assert scene.radii[0] > 0, "stored float32 radius is 0"


def test_random_spheres_camera_outside_for_tiny_n():
    for n in (1, 2):
        for seed in range(20):
            scene = random_spheres(n, seed)
            distance = np.linalg.norm(scene.centers.astype(np.float64), axis=1)
            assert (distance > scene.radii).all(), f"n={n} seed={seed}: camera inside a sphere"


def test_random_spheres_fill_the_16_10_view():
    """random_spheres' centres are uniform over the view of a 16:10 picture
    from the default camera (60 degrees high), at depths 5 to 25: every centre
    inside that view, both edges of each axis reached, neither side favoured;
    so a changed aspect, field of view or range of either axis fails."""
    scene = random_spheres(20000, seed=3)
    x, y, z = scene.centers.astype(np.float64).T
    half_h = np.tan(np.radians(30.0))
    half_w = half_h * 16 / 10
    assert 5.0 <= z.min() and z.max() <= 25.0
    for across, half in ((x / z, half_w), (y / z, half_h)):
        assert np.abs(across).max() <= half * (1 + 1e-6)
        assert across.max() >= half * 0.99 and across.min() <= -half * 0.99
        assert abs(np.mean(across)) < 0.05 * half  # uniform: no side favoured
