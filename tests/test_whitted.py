"""Whitted shading: the kernels against the float64 reference (whitted_reference)
on fresh random scenes, its invariants, and every device against the CPU."""

import importlib
import math

import numpy as np
import pytest
import whitted_reference
from reference import to_bytes
from scenes import KINDS

import raybench
from raybench import Camera, Light, Material, Scene, backends, layout, lighting
from raybench.backends import bands


def material(rng, kind=None) -> Material:
    kind = rng.integers(4) if kind is None else kind
    if kind == 0:
        return Material()
    if kind == 1:
        return Material(specular=float(rng.uniform(0, 1)), shininess=float(rng.uniform(1, 200)))
    if kind == 2:
        return Material(specular=float(rng.uniform(0, 1)), reflect=float(rng.uniform(0.3, 1.0)))
    return Material(
        specular=float(rng.uniform(0, 1)),
        reflect=float(rng.uniform(0, 0.1)),
        transmit=float(rng.uniform(0.5, 0.9)),
        ior=float(rng.uniform(1.1, 2.4)),
    )


def lit_scene(rng, n, lights=True, camera=None):
    """n spheres of mixed materials in front of the default camera, the first
    glass near the middle of the view (so that every kind of ray is cast), on
    a floor that is a huge sphere, lit by a point light and an area light."""
    centers = np.stack([rng.uniform(-4, 4, n), rng.uniform(-2.5, 2.5, n), rng.uniform(6, 18, n)], axis=1)
    centers[0] = rng.uniform([-1, -1, 6], [1, 1, 9])
    radii = rng.uniform(0.3, 1.6, n)
    # a sphere that holds the glass, overlaps it or crosses the view's ray to its centre goes
    # back along z until it does none of these (one held it on a seed of CI's: no refraction)
    glass, toward = centers[0], centers[0] / np.linalg.norm(centers[0])
    for j in range(1, n):
        while True:
            along = float(np.clip(centers[j] @ toward, 0.0, glass @ toward))
            if (
                min(np.linalg.norm(centers[j] - glass), np.linalg.norm(centers[j] - along * toward))
                > radii[j] + radii[0] + 0.05
            ):
                break
            centers[j, 2] += radii[j] + radii[0]
    centers = np.concatenate([centers, [[0.0, -1003.0, 12.0]]])
    radii = np.concatenate([radii, [1000.0]])
    lamps = []
    if lights:
        lamps = [
            Light(position=tuple(rng.uniform([-6, 4, -2], [6, 10, 6])), intensity=float(rng.uniform(0.4, 0.9))),
            Light(
                position=tuple(rng.uniform([-6, 4, -2], [6, 10, 6])),
                color=tuple(rng.uniform(0.5, 1.0, 3)),
                intensity=float(rng.uniform(0.4, 0.9)),
                radius=float(rng.uniform(0.2, 1.5)),
            ),
        ]
    return Scene(
        centers,
        radii,
        rng.uniform(0, 1, (n + 1, 3)),
        camera,
        materials=[material(rng, kind=3)] + [material(rng) for _ in range(n)],
        lights=lamps,
        ambient=tuple(rng.uniform(0, 0.2, 3)),
        background=None if rng.uniform() < 0.5 else tuple(rng.uniform(0, 1, 3)),
    )


def frame(scene, device, width, height, camera=None, depth=5, samples=3, **options):
    return raybench.render(
        scene, camera, width, height, device=device, shading="whitted", depth=depth, shadow_samples=samples, **options
    )


def check_against_reference(got, ref, context, max_off=0.02):
    """Hits the reference's wherever they agree closely enough that float32
    cannot decide otherwise (all but a few edge pixels), colours within 2
    steps but at a few pixels (grazing rays, shadow edges), ray counts within
    a few percent (a weight near the cut-off or a grazing hit may go either
    way)."""
    n = got.hits.size
    hits_off = (got.hits != ref.hits).sum()
    assert hits_off <= max(1, 0.005 * n), f"{context}: {hits_off} of {n} pixels hit another sphere"
    steps = np.abs(got.image.astype(int) - to_bytes(ref.color).astype(int)).max(axis=2)
    off = (steps > 2).mean()
    assert off <= max_off, f"{context}: {off:.1%} of pixels more than 2 steps from the reference (max {steps.max()})"
    counts = np.array([got.rays[k] for k in layout.KINDS])
    assert counts[0] == ref.rays[0] == n
    assert np.all(np.abs(counts - ref.rays) <= 0.03 * ref.rays + 2), f"{context}: rays {counts} vs {ref.rays}"


@pytest.mark.slow
@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_cpu_matches_the_float64_reference(rng, accel):
    scene = lit_scene(rng, 12)
    shading = lighting.Shading.of(scene, 5, 3)
    ref = whitted_reference.trace(scene, shading, Camera(), 48, 32)
    got = frame(scene, "cpu", 48, 32, accel=accel)
    check_against_reference(got, ref, f"cpu {accel}")
    assert got.rays["shadow"] > 0 and got.rays["reflection"] > 0 and got.rays["refraction"] > 0


def test_camera_inside_a_glass_sphere(rng):
    scene = lit_scene(rng, 8)
    glass = Scene(
        np.concatenate([scene.centers, [[0.2, -0.1, 0.3]]]),
        np.concatenate([scene.radii, [2.5]]),
        np.concatenate([scene.colors, [[1.0, 1.0, 1.0]]]),
        materials=[*scene.materials, Material(transmit=0.95, ior=1.33)],
        lights=scene.lights,
        ambient=scene.ambient,
        background=scene.background,
    )
    shading = lighting.Shading.of(glass, 5, 2)
    ref = whitted_reference.trace(glass, shading, Camera(), 40, 30)
    got = frame(glass, "cpu", 40, 30, samples=2)
    assert (got.hits == len(glass) - 1).all()  # every primary ray meets the glass from inside
    check_against_reference(got, ref, "camera in glass")


@pytest.mark.parametrize("kind", [k for k in KINDS if k != "inside"])
@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_no_lights_no_mirrors_is_the_thesis_picture(rng, kind, accel):
    """With the camera outside every sphere: Whitted shading of a scene
    without lights, mirrors or glass is the thesis's picture, bit for bit."""
    scene, camera = KINDS[kind](rng, 40)
    thesis = raybench.render(scene, camera, 40, 30, device="cpu", accel=accel)
    lit = raybench.render(scene, camera, 40, 30, device="cpu", accel=accel, shading="whitted")
    assert np.array_equal(thesis.image, lit.image) and np.array_equal(thesis.hits, lit.hits)
    assert lit.rays == {"primary": 1200, "shadow": 0, "reflection": 0, "refraction": 0}


def test_a_sphere_shadows_the_floor_where_the_reference_says(rng):
    """A point light above a sphere over a floor: the floor's pixels in the
    shadow are those the reference finds blocked, but at the shadow's edge."""
    side = float(rng.choice([-1, 1]) * rng.uniform(2, 4))
    scene = Scene(
        [[0.0, -1000.0, 10.0], [float(rng.uniform(-1, 1)), float(rng.uniform(1.2, 2.0)), 10.0]],
        [1000.0, 0.8],
        [[0.8, 0.8, 0.8], [0.9, 0.2, 0.2]],
        Camera(position=(0, 4, 0), look_at=(0, 0, 10)),
        lights=[Light(position=(side, 7.0, float(rng.uniform(8, 12))))],
        ambient=(0.05, 0.05, 0.05),
    )
    shading = lighting.Shading.of(scene, 5, 1)
    ref = whitted_reference.trace(scene, shading, scene.camera, 80, 60)
    got = frame(scene, "cpu", 80, 60)
    floor = (ref.hits == 0) & (got.hits == 0)
    dark_ref = floor & (ref.color.sum(axis=2) < 0.5)
    dark_got = floor & (got.image.astype(int).sum(axis=2) < 0.5 * 255)
    assert dark_ref.sum() > 20, "the test scene casts no shadow in view"
    differ = dark_ref ^ dark_got
    edge = dark_ref ^ np.roll(dark_ref, 1, 0) | dark_ref ^ np.roll(dark_ref, 1, 1)
    edge = edge | np.roll(edge, -1, 0) | np.roll(edge, -1, 1)
    assert not (differ & ~edge).any(), f"{(differ & ~edge).sum()} floor pixels shadowed unlike the reference"


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.gpu)])
@pytest.mark.parametrize("depth", [0, 1, 4, 5, 9])
def test_facing_mirrors_stop_at_the_depth_limit(device, depth):
    """Between two facing mirrors the ray bounces depth times, then stops."""
    scene = Scene(
        [[0.0, 0.0, 3.0], [0.0, 0.0, -3.0]],
        [1.0, 1.0],
        [[0.5, 0.5, 0.5]] * 2,
        materials=[Material(reflect=1.0)] * 2,
    )
    got = frame(scene, device, 1, 1, Camera(fov_deg=1.0), depth=depth)
    assert got.rays == {"primary": 1, "shadow": 0, "reflection": depth, "refraction": 0}


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.gpu)])
def test_total_internal_reflection_inside_glass(device):
    """From inside a glass ball (ior 1.5, critical angle 41.8 degrees) a ray
    meeting the surface at 64 degrees is all reflected, at every bounce (a
    chord keeps its angle); at 26 degrees it leaves, and is refracted."""
    glass = Material(transmit=1.0, ior=1.5)
    scene = Scene([[0.0, 0.0, 0.0]], [1.0], [[1.0, 1.0, 1.0]], materials=[glass])
    steep = Camera(position=(0.9, 0.0, 0.0), look_at=(0.9, 1.0, 0.0), up=(0, 0, 1), fov_deg=1.0)
    got = frame(scene, device, 1, 1, steep, depth=6)
    assert math.degrees(math.acos(math.sqrt(1 - 0.9**2))) > 41.8
    assert got.rays == {"primary": 1, "shadow": 0, "reflection": 6, "refraction": 0}
    assert got.image.max() == 0  # all the light is lost at the depth limit
    shallow = Camera(position=(0.44, 0.0, 0.0), look_at=(0.44, 1.0, 0.0), up=(0, 0, 1), fov_deg=1.0)
    got = frame(scene, device, 1, 1, shallow, depth=1)
    assert got.rays["refraction"] == 1 and got.rays["reflection"] == 1


@pytest.mark.gpu
def test_brute_force_is_the_bvh_bit_for_bit(rng):
    """Whitted's rays by brute force (trace.scan) and through the BVH
    (traverse.leaf_test) make the same test on the same float32 values, the
    sphere a ray leaves skipped or met at its far root alike: the same frame
    and the same rays, bit for bit, on a scene of mirrors and glass, where
    secondary rays meet the spheres from outside and from inside."""
    for _ in range(20):  # a scene whose frame has mirrors and glass enough that the check means something
        scene = raybench.random_spheres(40, seed=int(rng.integers(2**31)), materials=True)
        bvh = frame(scene, "cpu", 40, 25, accel="bvh", samples=2)
        if bvh.rays["reflection"] > 100 and bvh.rays["refraction"] > 50:
            break
    else:
        pytest.fail("20 random scenes in a row with too few reflected or refracted rays")
    none = frame(scene, "cpu", 40, 25, accel="none", samples=2)
    assert np.array_equal(bvh.hits, none.hits) and bvh.rays == none.rays
    assert np.array_equal(bvh.image, none.image), np.count_nonzero(bvh.image != none.image)


@pytest.mark.slow
@pytest.mark.parametrize("samples", [1, 5, 17, 64])
def test_cpu_packets_are_its_rays_one_at_a_time(rng, samples):
    """The CPU's Whitted program on the 4-wide tree (tree_width 4, the
    default): each tile's primary rays as one packet, the reflected and
    refracted rays through the wide tree, a hit's shadow rays to a light as
    packets; the frame, hits and rays of each ray walked alone through the
    binary tree (tree_width 2), bit for bit: for a point light (one ray),
    and area lights of packets under, over and many times what one holds
    (cpu.LANES), through glass and mirrors, on a frame of part tiles
    (cpu.PACKET_W x PACKET_H) cut into chunks for two threads; and once
    from a camera inside the glass sphere, whose primary rays meet it at
    its far root."""
    scene = lit_scene(rng, 30)
    camera = None
    if samples == 5:
        spheres = scene.spheres
        centre, radius = spheres[:3, 0].copy(), spheres[3, 0]
        # the spheres that overlap the glass moved out of it (one could hide its far side from
        # every ray); the floor, last, lies far below it
        for j in range(1, spheres.shape[1] - 1):
            away = spheres[:3, j] - centre
            length = float(np.linalg.norm(away))
            if length < radius + spheres[3, j] + 0.1:
                away = away / length if length > 1e-3 else np.array([1.0, 0.0, 0.0])
                spheres[:3, j] = centre + away * (radius + spheres[3, j] + 0.2)
        camera = Camera(position=tuple(centre), look_at=tuple(centre + [0.2, -0.1, 1.0]))
    alone = frame(scene, "cpu", 37, 20, camera, samples=samples, tree_width=2)
    packets = frame(scene, "cpu", 37, 20, camera, samples=samples, threads=2)
    assert packets.rays["shadow"] > 0 and packets.rays["refraction"] > 0  # not vacuous
    assert np.array_equal(alone.hits, packets.hits) and alone.rays == packets.rays
    assert np.array_equal(alone.image, packets.image), np.count_nonzero(alone.image != packets.image)
    if camera is not None:  # inside the glass (no other sphere overlaps it), every ray meets its far side
        assert (packets.hits == 0).all()


def test_cpu_packets_stop_at_the_flag(rng):
    """The packets program reads the stop flag (Ctrl-C's, cpu.Tracer._finish)
    before each row of tiles: set, it returns and writes no pixel; cleared,
    the same call traces the frame."""
    scene = lit_scene(rng, 10)
    with backends.tracer("cpu", scene.spheres, 37, 20, shading=lighting.Shading.of(scene, 5, 1)) as tracer:
        args = tracer._kernel_args(Camera().basis(37, 20), tracer.count)
        tracer.image[:] = 7
        tracer._kernel(0, 20, *args, np.ones(1, np.uint8))
        assert (tracer.image == 7).all()
        tracer._kernel(0, 20, *args, np.zeros(1, np.uint8))
        assert (tracer.image != 7).any()


@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_cuda_gives_the_cpu_frame(rng, accel):
    """Bit for bit under numba's simulator, which rounds as the CPU does; on
    a GPU, whose compiler fuses multiply-adds, the same hits and colours
    within one step but at a few pixels where a shadow or glass path turns."""
    scene = lit_scene(rng, 10)
    cpu = frame(scene, "cpu", 24, 16, accel=accel, samples=2)
    gpu = frame(scene, "cuda", 24, 16, accel=accel, samples=2)
    if backends.module("cuda").simulated():
        assert np.array_equal(cpu.image, gpu.image) and np.array_equal(cpu.hits, gpu.hits)
        assert cpu.rays == gpu.rays
    else:
        steps = np.abs(cpu.image.astype(int) - gpu.image.astype(int)).max(axis=2)
        assert (steps > 1).mean() <= 0.01 and (cpu.hits != gpu.hits).mean() <= 0.005


def test_version_1_scenes_need_no_lights():
    """A scene without lights or materials is saved as version 1, and a
    version-1 file refuses version 2's fields."""
    plain = raybench.random_spheres(5)
    assert plain.to_dict()["version"] == 1
    doc = plain.to_dict()
    doc["lights"] = []
    with pytest.raises(raybench.RaybenchError, match=r"^lights: unknown field"):
        Scene.from_dict(doc)


def test_version_2_round_trip(tmp_path, rng):
    scene = lit_scene(rng, 6, camera=Camera(position=(0, 1, -2)))
    scene.save(tmp_path / "s.json")
    back = Scene.load(tmp_path / "s.json")
    assert back.to_dict() == scene.to_dict() and back.to_dict()["version"] == 2
    assert np.array_equal(back.spheres, scene.spheres)
    np.testing.assert_array_equal(lighting.Shading.of(back).materials, lighting.Shading.of(scene).materials)


def test_numpy_scalars_make_a_scene_that_saves(tmp_path, rng):
    """A material or light given NumPy scalars keeps Python floats: the scene
    saves as JSON and loads back the same."""
    scene = Scene(
        np.zeros((1, 3)), np.ones(1), np.ones((1, 3)),
        materials=[Material(ior=np.float32(1.5), transmit=np.float64(0.5), shininess=np.int64(8))],
        lights=[Light(position=(0, 5, 0), intensity=np.float32(0.5), radius=np.float16(0.25))],
    )  # fmt: skip
    scene.save(tmp_path / "s.json")
    back = Scene.load(tmp_path / "s.json")
    assert back.to_dict() == scene.to_dict() and type(back.materials[0].ior) is float


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d["spheres"][3].update(material={"ior": -1}), r"spheres\[3\]\.material\.ior: must be >= 0\.01"),
        # an index that float32 would round to 0 (a division by zero in the kernels), or near it
        (lambda d: d["spheres"][3].update(material={"ior": 1e-50, "transmit": 1}), r"material\.ior: must be >= 0\.01"),
        (lambda d: d["spheres"][0].update(material={"ior": 10**400}), r"material\.ior: must be a finite number, got a"),
        (lambda d: d["lights"][0].update(intensity=float("nan")), r"lights\[0\]\.intensity: must be a finite number"),
        (lambda d: d["spheres"][0].update(material={"reflect": 0.7, "transmit": 0.6}), r"reflect \+ transmit"),
        (lambda d: d["spheres"][1].update(material={"shiny": 1}), r"spheres\[1\]\.material\.shiny: unknown"),
        (lambda d: d["spheres"][2].update(material={"reflect": True}), r"material\.reflect: must be a number"),
        (lambda d: d["lights"].append({"color": [1, 1, 1]}), r"lights\[2\]\.position: missing"),
        (lambda d: d["lights"][0].update(intensity=-2), r"lights\[0\]\.intensity: must be >= 0"),
        (lambda d: d["lights"][1].update(radius="big"), r"lights\[1\]\.radius: must be a number"),
        (lambda d: d["lights"][0].update(color=[2, 0, 0]), r"lights\[0\]\.color: each channel"),
        (lambda d: d.update(ambient=[0.1, 0.1]), r"ambient: must be a list of 3 numbers"),
        (lambda d: d.update(background="blue"), r"background: must be a list of 3 numbers"),
        (lambda d: d.update(lights={}), r"lights: must be a list"),
        (lambda d: d.update(version=4), r"version: this raybench reads versions 1 to 3, got 4"),
    ],
)
def test_version_2_bad_fields_are_named(rng, edit, message):
    doc = lit_scene(rng, 5).to_dict()
    edit(doc)
    with pytest.raises(raybench.RaybenchError, match=message):
        Scene.from_dict(doc)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"depth": 17}, r"depth: must be an integer from 0 to 16"),
        ({"depth": 2.0}, r"depth: must be an integer"),
        ({"shadow_samples": 0}, r"shadow_samples: must be an integer from 1 to 64"),
        ({"shading": "phong"}, r"shading: must be one of thesis, whitted"),
        ({"shading": "whitted", "kernel": "fast", "accel": "none"}, r"kernel 'fast': applies to the thesis"),
    ],
)
def test_bad_whitted_options_are_refused(kwargs, message):
    options = {"shading": "whitted", **kwargs}
    with pytest.raises(raybench.RaybenchError, match=message):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cpu", **options)


def test_thesis_shading_takes_no_depth():
    with pytest.raises(raybench.RaybenchError, match="apply to shading='whitted' only"):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cpu", depth=3)


def test_the_example_scenes_load_and_render():
    from raybench import examples

    scene = Scene.load(examples.path("whitted"))
    got = raybench.render(scene, width=32, height=20, device="cpu", shading="whitted")
    assert got.rays["shadow"] > 0 and got.rays["reflection"] > 0 and got.rays["refraction"] > 0
    mixed = raybench.random_spheres(200, seed=4, materials=True)
    assert np.array_equal(mixed.spheres, raybench.random_spheres(200, seed=4).spheres)  # same geometry
    kinds = {(m.reflect > 0.3, m.transmit > 0) for m in mixed.materials}
    assert kinds == {(False, False), (True, False), (False, True)}


@pytest.mark.gpu
@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_wgpu_gives_the_cpu_frame(rng, accel, adapter):
    """lavapipe rounds the arithmetic as the CPU does: the same hits and
    rays, bit for bit, and the same bytes but at a rare pixel one step off
    (its math library need not round a function's last bit as the CPU's
    does, which can move a colour across a byte's boundary); a GPU's compiler may
    fuse multiply-adds: then the CPU's hits and colours within one step but
    at a few pixels where a shadow or glass path turns."""
    scene = lit_scene(rng, 10)
    cpu = frame(scene, "cpu", 40, 24, accel=accel, samples=2)
    gpu = frame(scene, "wgpu", 40, 24, accel=accel, samples=2, adapter=adapter)
    assert cpu.rays["primary"] == gpu.rays["primary"] == 40 * 24
    steps = np.abs(cpu.image.astype(int) - gpu.image.astype(int)).max(axis=2)
    if backends.module("wgpu").choose(adapter).type == "CPU":
        assert np.array_equal(cpu.hits, gpu.hits) and cpu.rays == gpu.rays
        assert steps.max() <= 1 and (steps > 0).mean() <= 0.005, (steps.max(), (steps > 0).sum())
    else:
        assert (steps > 1).mean() <= 0.01 and (cpu.hits != gpu.hits).mean() <= 0.005


@pytest.mark.gpu
@pytest.mark.slow
def test_wgpu_brute_force_is_its_bvh_on_a_large_scene(adapter):
    """Brute force and the BVH give one Whitted frame on wgpu, 1,000 spheres,
    where a pixel's rays test the spheres over 65,535 times: more than
    lavapipe's loop limiter lets one invocation run (brute.wgsl says so),
    so this runs on GPU adapters only."""
    if backends.module("wgpu").choose(adapter).type == "CPU":
        pytest.skip("a CPU adapter (lavapipe) cuts loops of over 65,535 trips short: brute.wgsl")
    scene = raybench.random_spheres(1000, seed=0, materials=True)
    frames = [frame(scene, "wgpu", 160, 100, accel=accel, samples=4, adapter=adapter) for accel in ("none", "bvh")]
    assert frames[0].rays == frames[1].rays
    assert np.array_equal(frames[0].image, frames[1].image) and np.array_equal(frames[0].hits, frames[1].hits)


# Light that adds up: lossless spheres in a uniform background (a white furnace)
# vanish, glass of the surrounding index is invisible, and only rays that can
# change the picture are cast.
EVERY_DEVICE = ["cpu", pytest.param("cuda", marks=pytest.mark.gpu), pytest.param("wgpu", marks=pytest.mark.gpu)]
# cuda under numba's simulator takes 5 s or more a case here (the project's mark for slow)
EVERY_DEVICE_SLOW_CUDA = [
    "cpu",
    pytest.param("cuda", marks=[pytest.mark.gpu, pytest.mark.slow]),
    pytest.param("wgpu", marks=pytest.mark.gpu),
]


def device_options(device, request) -> dict:
    return {"adapter": request.getfixturevalue("adapter")} if device == "wgpu" else {}


def lossless_scene(rng, n, lights):
    """n (1 to 4) spheres apart that absorb nothing and show no light of
    their own: clear glass (transmit 1, random index) or perfect mirrors
    (reflect 1), with random colours that must not show, in front of the
    camera at z = 5 to 9, in a uniform background of a random colour."""
    if n == 1:
        centers, radii = [rng.uniform([-0.5, -0.3, 5], [0.5, 0.3, 9])], [rng.uniform(1.2, 2.0)]
    else:  # one to a cell of a 2x2 grid, jittered: never two overlapping (cells 2.3 apart at least)
        cells = rng.permutation([(-2.3, -1.3), (2.3, -1.3), (-2.3, 1.3), (2.3, 1.3)])[:n]
        centers = [(x + rng.uniform(-0.15, 0.15), y + rng.uniform(-0.15, 0.15), rng.uniform(6, 9)) for x, y in cells]
        radii = list(rng.uniform(0.9, 1.1, n))
    kinds = rng.integers(2, size=n)
    kinds[0] = 0  # glass at least once
    materials = [
        Material(transmit=1.0, ior=float(rng.uniform(1.1, 2.4))) if k == 0 else Material(reflect=1.0) for k in kinds
    ]
    lamps = [Light(position=tuple(rng.uniform([-6, 4, -2], [6, 10, 6])), radius=0.5)] if lights else []
    return Scene(
        np.array(centers),
        np.array(radii),
        rng.uniform(0, 1, (n, 3)),
        Camera(position=(0, 0, 0), look_at=(0, 0, 8)),
        materials=materials,
        lights=lamps,
        ambient=(0.1, 0.1, 0.1),
        background=tuple(rng.uniform(0.2, 1.0, 3)),
    )


@pytest.mark.parametrize("device", EVERY_DEVICE_SLOW_CUDA)
@pytest.mark.parametrize("n", [1, 4])
def test_lossless_spheres_vanish_in_a_uniform_background(rng, request, device, n):
    """Every path ends in the background with all its weight, so each pixel
    is the background within one step; but for the weight that meets the
    depth limit (the float64 reference's `truncated`: where the model says
    some does, the pixel is darker by that much). The dropped branches add
    up to under half a step, so they cannot darken it (with each branch
    under half a step dropped, as before, three glass balls darkened it by
    4 steps). Such spheres cast no shadow ray: none of their own light shows."""
    scene = lossless_scene(rng, n, lights=bool(rng.integers(2)))
    got = frame(scene, device, 36, 24, depth=16, samples=2, **device_options(device, request))
    ref = whitted_reference.trace(scene, lighting.Shading.of(scene, 16, 2), scene.camera, 36, 24)
    background = to_bytes(np.array(scene.background)).astype(int)
    assert (got.image.astype(int) <= background + 1).all()  # no light is made
    # Where the model's paths all end before the limit, the background within
    # a step; but for the rare path that float32 turns otherwise and sends
    # into a long chain of bounces between spheres.
    clean = ref.truncated < 0.5 / 255
    steps = np.abs(got.image.astype(int) - background).max(axis=2)
    assert (steps[clean] > 1).mean() <= 0.005, f"{(steps[clean] > 1).sum()} pixels off, by up to {steps.max()}"
    # Where the limit stops some weight, darker by that much.
    expected = to_bytes(np.array(scene.background) * (1.0 - ref.truncated)[..., None]).astype(int)
    assert (np.abs(got.image.astype(int) - expected).max(axis=2) > 1).mean() <= 0.01
    assert (clean & (got.hits >= 0)).sum() > 20  # not vacuous: many sphere pixels held to the background
    assert got.rays["reflection"] + got.rays["refraction"] > 20
    assert got.rays["shadow"] == 0


@pytest.mark.parametrize("device", EVERY_DEVICE)
def test_three_glass_balls_vanish(request, device):
    """The reproduction that found the darkening: three clear balls on the
    axis, the centre pixel the background's [204, 128, 77] within a step."""
    glass = Material(transmit=1.0, ior=1.5)
    scene = Scene(
        np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.1], [0.0, 0.0, 2.2]]),
        np.full(3, 0.5),
        np.zeros((3, 3)),
        Camera(position=(0, 0, -4), look_at=(0, 0, 0), fov_deg=30),
        materials=[glass] * 3,
        background=(0.8, 0.5, 0.3),
    )
    got = frame(scene, device, 11, 7, depth=16, **device_options(device, request))
    assert got.hits[3, 5] == 0
    assert np.abs(got.image[3, 5].astype(int) - [204, 128, 77]).max() <= 1, got.image[3, 5]


@pytest.mark.parametrize("device", EVERY_DEVICE_SLOW_CUDA)
def test_index_matched_glass_is_invisible(rng, request, device):
    """Glass of index 1 in air reflects nothing (exact Fresnel; Schlick left
    it a rim) and bends nothing: the frame with it is the frame without it,
    within a step (the rays behind it start from its far side), on random
    opaque spheres of the thesis's shading."""
    n = 6
    centers = np.stack([rng.uniform(-3, 3, n), rng.uniform(-2, 2, n), rng.uniform(10, 16, n)], axis=1)
    radii = rng.uniform(0.5, 1.5, n)
    colors = rng.uniform(0, 1, (n, 3))
    camera = Camera(position=(0, 0, 0), look_at=(0, 0, 1))
    background = None if rng.uniform() < 0.5 else tuple(rng.uniform(0, 1, 3))
    plain = Scene(centers, radii, colors, camera, materials=[Material()] * n, background=background)
    glass = Scene(
        np.concatenate([centers, [[rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 5.0]]]),
        np.concatenate([radii, [rng.uniform(1.5, 2.5)]]),
        np.concatenate([colors, rng.uniform(0, 1, (1, 3))]),
        camera,
        materials=[Material()] * n + [Material(transmit=1.0, ior=1.0)],
        background=background,
    )
    options = device_options(device, request)
    without = frame(plain, device, 40, 30, depth=4, **options)
    with_glass = frame(glass, device, 40, 30, depth=4, **options)
    covered = with_glass.hits == n
    assert covered.sum() > 60  # the glass covers much of the frame
    steps = np.abs(without.image.astype(int) - with_glass.image.astype(int)).max(axis=2)
    # The ray behind the glass starts from its far side, rounded in float32: where it grazes a
    # sphere's silhouette it may meet the neighbour's primitive instead (a seed found one pixel).
    # So a pixel off by more than a step must lie on a silhouette of the frame without the
    # glass (its 3x3 neighbours hit more than one primitive), and there may be two at most.
    around = np.lib.stride_tricks.sliding_window_view(np.pad(without.hits, 1, mode="edge"), (3, 3))
    silhouette = around.min(axis=(2, 3)) != around.max(axis=(2, 3))
    off = steps > 1
    assert not (off & ~silhouette).any(), f"{(off & ~silhouette).sum()} pixels off inside, up to {steps.max()} steps"
    assert off.sum() <= 2, f"{off.sum()} pixels off, by up to {steps.max()} steps"
    assert with_glass.rays["reflection"] == 0 and with_glass.rays["refraction"] == 2 * covered.sum()


@pytest.mark.parametrize("device", EVERY_DEVICE)
def test_only_shadow_rays_that_can_count_are_cast(request, device):
    """A perfect mirror without a glint shows none of its own light: it casts
    no shadow ray. Give it a glint, or keep some of its weight for its
    colour, and it casts one to the point light from every lit hit."""
    light = Light(position=(3.0, 4.0, -3.0))
    options = device_options(device, request)
    counts = {}
    for name, mirror in [
        ("perfect", Material(reflect=1.0)),
        ("glint", Material(reflect=1.0, specular=0.5)),
        ("tinted", Material(reflect=0.9)),
    ]:
        scene = Scene(
            np.zeros((1, 3)), np.ones(1), np.ones((1, 3)), Camera(position=(0, 0, -5)),
            materials=[mirror], lights=[light], background=(0.3, 0.3, 0.3),
        )  # fmt: skip
        got = frame(scene, device, 32, 24, depth=3, **options)
        counts[name] = got.rays["shadow"]
        assert got.rays["reflection"] == (got.hits >= 0).sum() > 50
    assert counts["perfect"] == 0
    assert counts["glint"] == counts["tinted"] > 20


# The wavefront (the GPUs' default under Whitted shading) casts the
# per-pixel program's rays and sums the same light, in another order.
GPUS = [pytest.param("cuda", marks=[pytest.mark.gpu, pytest.mark.slow]), pytest.param("wgpu", marks=pytest.mark.gpu)]


def schedules(scene, device, width, height, request, **options):
    options = {**options, **device_options(device, request)}
    return [frame(scene, device, width, height, schedule=s, **options) for s in ("pixel", "wavefront")]


def rounds_as_the_cpu(device, request) -> bool:
    """Whether the device rounds as the CPU does: numba's simulator, or a CPU
    adapter (lavapipe)."""
    if device == "cuda":
        return backends.module("cuda").simulated()
    return backends.module("wgpu").choose(request.getfixturevalue("adapter")).type == "CPU"


def assert_same_frame(pixel, wave, exact):
    """Where the device rounds as the CPU does, the same hits and rays, and
    the same bytes but where a sum rounds to the other side of a step: the
    wavefront sums a pixel's light as integers (fixed point), the pixel
    program as floats, and a sum within an ulp of a half step can round
    either way (a CI seed found such a pixel, in the code before the
    primitive seam too). On a GPU within a step but at a few pixels, as the
    CPU against the GPU."""
    if exact:
        assert np.array_equal(pixel.hits, wave.hits) and pixel.rays == wave.rays
        steps = np.abs(pixel.image.astype(int) - wave.image.astype(int)).max(axis=2)
        assert steps.max() <= 1 and (steps > 0).mean() <= 0.01, (steps.max(), (steps > 0).sum())
    else:
        steps = np.abs(pixel.image.astype(int) - wave.image.astype(int)).max(axis=2)
        assert (steps > 1).mean() <= 0.01 and (pixel.hits != wave.hits).mean() <= 0.005
        for kind in KINDS_OF_RAYS:
            assert abs(pixel.rays[kind] - wave.rays[kind]) <= 0.01 * pixel.rays[kind] + 2


KINDS_OF_RAYS = ("primary", "shadow", "reflection", "refraction")


@pytest.mark.parametrize("device", GPUS)
@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_the_wavefront_is_the_pixel_program(rng, request, device, accel):
    pixel, wave = schedules(lit_scene(rng, 10), device, 24, 16, request, accel=accel, samples=2)
    assert wave.rays["reflection"] > 0 and wave.rays["refraction"] > 0 and wave.rays["shadow"] > 0
    assert_same_frame(pixel, wave, rounds_as_the_cpu(device, request))


@pytest.mark.gpu
@pytest.mark.slow
def test_cuda_wavefront_sees_spheres_moved_by_a_refit(rng):
    """cuda's wavefront reads the ordered spheres from a copy of its own (a
    row a sphere, made after each build): after spheres move and the GPU's
    tree is refitted, not rebuilt, the frame shows them where they are
    now, as brute force does."""
    scene = lit_scene(rng, 12)
    shading = lighting.Shading.of(scene, 3, 2)
    width, height = 24, 16
    basis = Camera().basis(width, height)
    moved = scene.spheres.copy()
    moved[:3, :-1] += rng.normal(0, 0.2, (3, moved.shape[1] - 1)).astype(np.float32)  # the floor stays
    with backends.tracer("cuda", scene.spheres, width, height, build="gpu", refit_limit=float("inf"),
                         shading=shading) as tracer:  # fmt: skip
        tracer.trace(basis)
        assert tracer.update(moved) == "refit"
        got = tracer.trace(basis)[0].copy()
    with backends.tracer("cuda", moved, width, height, accel="none", shading=shading) as brute:
        want = brute.trace(basis)[0]
    exact = backends.module("cuda").simulated()
    assert np.array_equal(got, want) if exact else (np.abs(got.astype(int) - want.astype(int)) > 1).mean() <= 0.01


@pytest.mark.parametrize("device", GPUS)
def test_the_wavefronts_queues_grow_to_hold_a_frame(request, device):
    """A frame whose waves outgrow the queues a wavefront starts with (a ray
    and two shadow rays a pixel): glass that fills the view, with a glint
    (so its shadow rays are cast) under two area lights, so every primary
    hit casts 8 shadow rays and spawns two children. The frame is traced
    again with longer queues, and comes out the pixel program's."""
    glass = Material(specular=0.5, reflect=0.1, transmit=0.8, ior=1.5)
    lamps = [Light(position=(-3.0, 4.0, -4.0), radius=0.5), Light(position=(3.0, 4.0, -4.0), radius=0.5)]
    scene = Scene(np.zeros((1, 3)), np.array([3.0]), np.ones((1, 3)), Camera(position=(0, 0, -5)),
                  materials=[glass], lights=lamps, background=(0.3, 0.4, 0.5))  # fmt: skip
    options = device_options(device, request)
    tracer = backends.tracer(device, scene.spheres, 12, 8, shading=lighting.Shading.of(scene, 3, 4), **options)
    first = tracer.trace(Camera(position=(0, 0, -5)).basis(12, 8))[0].copy()
    assert tracer.wavefront.retraced >= 1
    assert tracer.ray_counts[1] >= 8 * 12 * 8 and tracer.ray_counts[2] + tracer.ray_counts[3] >= 2 * 12 * 8
    pixel, wave = schedules(scene, device, 12, 8, request, depth=3, samples=4)
    assert np.array_equal(first, wave.image)
    assert_same_frame(pixel, wave, rounds_as_the_cpu(device, request))


@pytest.mark.parametrize(
    "options, message",
    [
        ({"schedule": "warp"}, r"schedule: must be one of wavefront, pixel"),
        ({"shading": "thesis", "schedule": "pixel"}, r"schedule 'pixel': applies to Whitted shading only"),
    ],
)
@pytest.mark.parametrize(
    "device", [pytest.param("cuda", marks=pytest.mark.gpu), pytest.param("wgpu", marks=pytest.mark.gpu)]
)
def test_bad_schedules_are_refused(request, device, options, message):
    options = {"shading": "whitted", **options, **device_options(device, request)}
    with pytest.raises(raybench.RaybenchError, match=message):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device=device, **options)


@pytest.mark.gpu
def test_a_wave_grid_is_checked():
    with pytest.raises(raybench.RaybenchError, match=r"wave_grid: must be an integer from 1"):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cuda", shading="whitted", wave_grid=0)


# A frame whose queues would not fit the device is traced in bands of rows
# (backends/bands.py); QUEUE_BYTES, lowered here, stands for a device of small
# buffers (or little free memory), so that small frames are banded.


def queue_bytes(device, tracer) -> int:
    """The bytes of the largest of the tracer's wavefront's queue buffers, as planned now."""
    module = importlib.import_module(f"raybench.backends.{device}.wavefront")
    plan, width = tracer.wavefront.plan, tracer.width
    return max(b.bytes(plan.rays, plan.shadows, plan.rows * width) for b in module.QUEUES)


def whitted_tracer(device, scene, width, height, request, depth, samples):
    shading = lighting.Shading.of(scene, depth, samples)
    return backends.tracer(device, scene.spheres, width, height, shading=shading, **device_options(device, request))


def assert_traced_alike(one, banded, basis):
    """The banded tracer's frame, hits and ray counts are the one-piece one's, bit for bit."""
    image, hits = (a.copy() for a in one.trace(basis))
    got_image, got_hits = banded.trace(basis)
    assert np.array_equal(image, got_image) and np.array_equal(hits, got_hits)
    assert np.array_equal(one.ray_counts, banded.ray_counts)


@pytest.mark.gpu
def test_a_frame_whose_queues_do_not_fit_is_traced_in_bands(rng, request, monkeypatch):
    """Queues that hold half the frame's rows: the frame in bands is the frame
    in one piece (each pixel's rays stay in its band), twice over (the sums
    each band zeroes for the next frame). On wgpu (lavapipe): the simulator
    takes a minute and a half for it; cuda's bands are tested below."""
    device, scene = "wgpu", lit_scene(rng, 10)
    width, height = 24, 16
    one = whitted_tracer(device, scene, width, height, request, 3, 2)
    monkeypatch.setattr(bands, "QUEUE_BYTES", queue_bytes(device, one) // 2)
    banded = whitted_tracer(device, scene, width, height, request, 3, 2)
    assert 1 <= banded.wavefront.plan.rows <= height // 2
    cast = 0
    for camera in (Camera(), Camera(position=tuple(rng.uniform([-1, -1, -2], [1, 1, 0])))):
        assert_traced_alike(one, banded, camera.basis(width, height))
        cast = cast + banded.ray_counts
    # not vacuous over the two frames: the second camera, placed at random, may not see the glass
    assert cast[2] > 0 and cast[3] > 0


@pytest.mark.parametrize("device", GPUS)
def test_queues_that_cannot_grow_are_split_into_bands(request, monkeypatch, device):
    """Glass that fills the view (test_the_wavefronts_queues_grow_to_hold_a_frame)
    overflows queues of a ray a pixel that just fit the device: they cannot
    grow, so the frame is traced again in bands, each with longer queues."""
    glass = Material(specular=0.5, reflect=0.1, transmit=0.8, ior=1.5)
    lamps = [Light(position=(-3.0, 4.0, -4.0), radius=0.5), Light(position=(3.0, 4.0, -4.0), radius=0.5)]
    scene = Scene(np.zeros((1, 3)), np.array([3.0]), np.ones((1, 3)), Camera(position=(0, 0, -5)),
                  materials=[glass], lights=lamps, background=(0.3, 0.4, 0.5))  # fmt: skip
    # the simulator: a frame of one block of rays, depth 1, a shadow ray a light
    width, height, depth, samples = (16, 8, 1, 1) if device == "cuda" else (24, 16, 2, 2)
    one = whitted_tracer(device, scene, width, height, request, depth, samples)
    monkeypatch.setattr(bands, "QUEUE_BYTES", queue_bytes(device, one))
    banded = whitted_tracer(device, scene, width, height, request, depth, samples)
    assert banded.wavefront.plan.rows == height
    assert_traced_alike(one, banded, scene.camera.basis(width, height))
    assert banded.wavefront.retraced >= 1 and banded.wavefront.plan.rows < height


@pytest.mark.parametrize("device", GPUS)
def test_queues_that_cannot_hold_one_row_are_refused(request, monkeypatch, device):
    monkeypatch.setattr(bands, "QUEUE_BYTES", 4096)
    with pytest.raises(raybench.RaybenchError, match=r"^schedule 'wavefront': one row of this frame needs queues of "
                       r"[0-9.]+ MiB, more than the queues' limit \(0\.0 MiB\); use a narrower frame"):  # fmt: skip
        raybench.render(raybench.random_spheres(3), width=64, height=8, device=device, shading="whitted",
                        **device_options(device, request))  # fmt: skip


def test_bands_plan_the_most_rows_that_fit(rng):
    """bands.plan on random sizes: every buffer within the limit, one row more
    over it, the bands covering the rows once."""
    for _ in range(200):
        check_plan(rng)


def check_plan(rng):
    width, rows = int(rng.integers(1, 300)), int(rng.integers(1, 300))
    rays, shadows = int(rng.integers(1, 8)) * width * rows, int(rng.integers(0, 20)) * width * rows
    buffers = [bands.Buffer(*(int(v) for v in rng.integers(0, 100, 4))) for _ in range(int(rng.integers(1, 4)))]
    limit = int(rng.integers(1, 2 * max(b.bytes(rays, shadows, width * rows) for b in buffers) + 2))
    least = int(rng.integers(1, 200))

    def slots(band):
        return max(least, -(-rays * band // rows)), max(least, -(-shadows * band // rows))

    def fits(band):
        return all(b.bytes(*slots(band), band * width) <= limit for b in buffers)

    try:
        plan = bands.plan(width, rows, rays, shadows, buffers, limit, least, "the limit")
    except raybench.RaybenchError as error:
        assert not fits(1) and "one row of this frame" in str(error)
        return
    assert fits(plan.rows) and (plan.rows == rows or not fits(plan.rows + 1))
    assert (plan.rays, plan.shadows) == slots(plan.rows)
    first = int(rng.integers(0, rows))
    covered = [row for top, bottom in plan.bands(first, rows) for row in range(top, bottom)]
    assert covered == list(range(first, rows))
