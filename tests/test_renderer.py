"""Renderer: a scene kept ready across frames gives render()'s frames."""

import weakref

import numpy as np
import pytest

import raybench
from raybench.render import KEEP_LENT


@pytest.mark.parametrize(
    "device, shading", [("cpu", "thesis"), ("cpu", "whitted"), pytest.param("cuda", "thesis", marks=pytest.mark.gpu)]
)
def test_frames_are_render_frames(rng, device, shading):
    scene = raybench.random_spheres(int(rng.integers(5, 60)), seed=int(rng.integers(2**31)), materials=True)
    # from anywhere near the default camera, towards the spheres: three different pictures
    cameras = [raybench.Camera(position=tuple(rng.uniform(-1, 1, 3)), look_at=(0, 0, 15)) for _ in range(3)]
    with raybench.Renderer(scene, 24, 16, device=device, shading=shading) as renderer:
        frames = [renderer.render(camera) for camera in cameras]
        assert renderer.render(cameras[0], hits=False).hits is None
    for camera, got in zip(cameras, frames):
        want = raybench.render(scene, camera, 24, 16, device=device, shading=shading)
        assert np.array_equal(got.image, want.image) and np.array_equal(got.hits, want.hits)
        assert got.rays == want.rays and (got.rays is None) == (shading == "thesis")
    # each frame owns its arrays: the next one did not overwrite them
    assert not all(np.array_equal(frames[0].image, f.image) for f in frames[1:])


def test_a_closed_renderer_says_so():
    renderer = raybench.Renderer(raybench.random_spheres(3), 8, 8, device="cpu")
    renderer.close()
    for call in (renderer.render, renderer.compile, lambda: renderer.update(raybench.random_spheres(3).spheres)):
        with pytest.raises(raybench.RaybenchError, match="renderer: it is closed"):
            call()


@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_count_and_update_give_the_frames_of_those_spheres(rng, accel):
    """render(count=k) is the frame of the scene's first k spheres, and after
    update(moved) the frame of the moved spheres: each against a one-shot
    render() of a scene made of exactly those spheres."""
    n = int(rng.integers(20, 80))
    scene = raybench.random_spheres(n, seed=int(rng.integers(2**31)))
    camera = raybench.Camera(position=tuple(rng.uniform(-0.5, 0.5, 3)))
    k = int(rng.integers(1, n))
    moved = scene.spheres.copy()
    moved[:3] += rng.uniform(-1.5, 1.5, (3, n)).astype(np.float32)
    with raybench.Renderer(scene, 40, 30, device="cpu", accel=accel) as renderer:
        assert renderer.compile() >= 0
        first_k = renderer.render(camera, count=k)
        assert renderer.update(moved) == ("build" if accel == "bvh" else None)
        after = renderer.render(camera)
        with pytest.raises(raybench.RaybenchError, match="sphere count"):
            renderer.render(camera, count=n + 1)
    moved_scene = raybench.Scene(moved[:3].T, moved[3], moved[4:7].T)
    for got, alone in ((first_k, scene.head(k)), (after, moved_scene)):
        want = raybench.render(alone, camera, 40, 30, device="cpu", accel=accel)
        assert np.array_equal(got.image, want.image) and np.array_equal(got.hits, want.hits)
    assert not np.array_equal(first_k.hits, after.hits)


def test_a_shading_made_ahead_is_whitted_shading(rng):
    scene = raybench.random_spheres(int(rng.integers(5, 40)), seed=int(rng.integers(2**31)), materials=True)
    depth, samples = int(rng.integers(1, 6)), int(rng.integers(1, 5))
    shading = raybench.lighting.Shading.of(scene, depth, samples)
    with raybench.Renderer(scene, 24, 16, device="cpu", shading=shading) as renderer:
        got = renderer.render()
    want = raybench.render(scene, None, 24, 16, device="cpu", shading="whitted", depth=depth, shadow_samples=samples)
    assert np.array_equal(got.image, want.image) and got.rays == want.rays
    with pytest.raises(raybench.RaybenchError, match="a Shading holds its own"):
        raybench.Renderer(scene, 8, 8, device="cpu", shading=shading, depth=2)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"scene": "x"}, "scene: must be a raybench.Scene"),
        ({"width": 0}, "size"),
        ({"depth": 3}, "apply to shading='whitted' only"),
        ({"shading": "flat"}, "shading: must be one of"),
    ],
)
def test_bad_arguments_are_refused(kwargs, message):
    args = {"scene": raybench.random_spheres(3), "width": 8, "height": 8, "device": "cpu", **kwargs}
    with pytest.raises(raybench.RaybenchError, match=message):
        raybench.Renderer(**args)


@pytest.mark.parametrize("accel, shading", [("bvh", "thesis"), ("none", "thesis"), ("bvh", "whitted")])
def test_rows_are_the_whole_frames_rows(rng, accel, shading):
    """Renderer.render(rows=...): a cluster's tile, each pixel as the whole frame has it.
    Between the two, a frame looking away (background only) fills the
    renderer's buffers, so a band left untraced cannot pass for traced."""
    scene = raybench.random_spheres(int(rng.integers(10, 60)), seed=int(rng.integers(2**31)), materials=True)
    camera = raybench.Camera(position=tuple(rng.uniform(-0.3, 0.3, 3)))
    away = raybench.Camera(position=camera.position, look_at=tuple(2 * np.array(camera.position) - camera.look_at))
    with raybench.Renderer(scene, 64, 48, device="cpu", threads=2, accel=accel, shading=shading) as renderer:
        whole = renderer.render(camera)
        # a band through a row that sees a sphere, so the test is not of background alone
        seen = int(rng.choice(np.flatnonzero((whole.hits >= 0).any(axis=1))))
        first = 8 * int(rng.integers(0, seen // 8 + 1))
        end = int(rng.integers(seen + 1, 49))
        assert (whole.hits[first:end] >= 0).any() and (renderer.render(away).hits == -1).all()
        band = renderer.render(camera, rows=(first, end))
        np.testing.assert_array_equal(band.image, whole.image[first:end])
        np.testing.assert_array_equal(band.hits, whole.hits[first:end])
        if shading == "whitted":  # the band's rays alone: one primary ray a pixel of it
            assert band.rays["primary"] == (end - first) * 64
            assert renderer.render(camera, rows=(0, 48)).rays == whole.rays
        for bad in [(3, 10), (8, 8), (0, 49), (-8, 8), "rows"]:
            with pytest.raises(raybench.RaybenchError, match="rows"):
                renderer.render(camera, rows=bad)


# Frames of their own arrays, not copies (Renderer.render; the tracer writes
# into arrays it is handed, recycled from Frames that are gone). On cuda, under
# numba's simulator where there is no GPU; wgpu where it finds an adapter.
OWN_ARRAYS_DEVICES = [
    "cpu",
    pytest.param("cuda", marks=pytest.mark.gpu),
    pytest.param("wgpu", marks=pytest.mark.gpu),
]


def _renderer(device, request, scene, width=24, height=16, **options):
    """A renderer on device; wgpu on the adapter the tests use."""
    if device == "wgpu":
        options["adapter"] = request.getfixturevalue("adapter")
    return raybench.Renderer(scene, width, height, device=device, **options)


def _cameras(rng, n):
    """n cameras near the default one, towards the spheres: different pictures."""
    return [raybench.Camera(position=tuple(rng.uniform(-1, 1, 3)), look_at=(0, 0, 15)) for _ in range(n)]


def _address(array) -> int:
    return array.__array_interface__["data"][0]


def _counting_host_arrays(renderer) -> list:
    """The data addresses of every array the renderer's tracer makes for
    frames from now on (its host_array, wrapped)."""
    made, make = [], renderer.tracer.host_array

    def host_array(shape, dtype):
        array = make(shape, dtype)
        made.append(_address(array))
        return array

    renderer.tracer.host_array = host_array
    return made


@pytest.mark.parametrize("device", OWN_ARRAYS_DEVICES)
def test_kept_frames_are_never_written(rng, device, request):
    """A frame the caller keeps, and a view of a frame the caller dropped, stay
    as they were traced through later frames of other cameras (frames
    dropped, hits=False, tiles, the tracer's own trace()), each against a
    copy taken at once."""
    scene = raybench.random_spheres(int(rng.integers(20, 40)), seed=int(rng.integers(2**31)))
    cameras = _cameras(rng, 3 if device == "cuda" else 8)  # numba's simulator: a second a frame
    with _renderer(device, request, scene) as renderer:
        kept = renderer.render(cameras[0])
        kept_copy = (kept.image.copy(), kept.hits.copy())
        dropped = renderer.render(cameras[1])
        image_rows, hit_column = dropped.image[4:9], dropped.hits[:, 5]
        weak = weakref.ref(dropped.hits)  # a weak reference alone could bring the array back
        views_copy = (image_rows.copy(), hit_column.copy(), dropped.hits.copy())
        del dropped
        for camera in cameras[2:]:
            renderer.render(camera)
            renderer.render(camera, hits=False)
            if renderer.tracer.traces_rows:
                renderer.render(camera, rows=(8, 16))
            renderer.tracer.trace(camera.basis(24, 16))
        assert not all(np.array_equal(kept_copy[0], renderer.render(c).image) for c in cameras[1:])
        np.testing.assert_array_equal(kept.image, kept_copy[0])
        np.testing.assert_array_equal(kept.hits, kept_copy[1])
        np.testing.assert_array_equal(image_rows, views_copy[0])
        np.testing.assert_array_equal(hit_column, views_copy[1])
        np.testing.assert_array_equal(weak(), views_copy[2])


@pytest.mark.parametrize("device", OWN_ARRAYS_DEVICES)
def test_dropped_frames_arrays_are_traced_into_again(rng, device, request):
    """Frames dropped in turn are traced into a few arrays, again and again:
    each frame's arrays are ones the tracer made for frames (not copies),
    and a frame dropped before the next is traced gives it its arrays."""
    scene = raybench.random_spheres(int(rng.integers(5, 40)), seed=int(rng.integers(2**31)))
    with _renderer(device, request, scene) as renderer:
        made = _counting_host_arrays(renderer)
        frame = renderer.render()
        for camera in _cameras(rng, 6):  # the last frame held while the next is traced
            frame = renderer.render(camera)
            assert {_address(frame.image), _address(frame.hits)} <= set(made)
        assert len(made) == 2 * 2  # an image and hits for the frame held, and for the next
        address = _address(frame.image), _address(frame.hits)
        del frame
        frame = renderer.render()
        assert (_address(frame.image), _address(frame.hits)) == address
        for _ in range(3):  # hits=False: the tracer's own hits, none made
            assert renderer.render(hits=False).hits is None
        assert len(made) == 2 * 2
        # frames kept: KEEP_LENT of them in the renderer's arrays, made once,
        # the rest copies, each of its own memory
        frames = [renderer.render() for _ in range(6)]
        assert len({_address(f.image) for f in [frame, *frames]}) == 7
        assert len(made) == 2 * KEEP_LENT
        lent = [f for f in [frame, *frames] if _address(f.image) in made]
        assert len(lent) == KEEP_LENT and all(_address(f.hits) in made for f in lent)
        # dropped again, their arrays are traced into again: no more made
        del frame, frames, lent
        for _ in range(3):
            frame = renderer.render()
            assert {_address(frame.image), _address(frame.hits)} <= set(made)
        assert len(made) == 2 * KEEP_LENT


@pytest.mark.parametrize(
    "device, accel",
    [
        ("cpu", "bvh"),
        ("cpu", "none"),
        pytest.param("cuda", "bvh", marks=pytest.mark.gpu),  # brute force: a minute on numba's simulator
        pytest.param("wgpu", "bvh", marks=pytest.mark.gpu),
        pytest.param("wgpu", "none", marks=pytest.mark.gpu),
    ],
)
def test_frames_in_recycled_arrays_are_the_tracers_frames(rng, device, accel, request):
    """Frames traced into arrays that held other frames are bit for bit the
    tracer's own trace() of a fresh tracer, hits=False and tiles included."""
    small = device == "cuda"  # numba's simulator: seconds a frame, more with every sphere of brute force
    scene = raybench.random_spheres(int(rng.integers(5, 15 if small else 80)), seed=int(rng.integers(2**31)))
    cameras = _cameras(rng, 3 if small else 5)
    width, height = (16, 16) if small else (32, 24)
    with _renderer(device, request, scene, width, height, accel=accel) as renderer:
        got = []
        for camera in cameras:
            renderer.render(cameras[0])  # dropped: its arrays are the next frame's
            frame = renderer.render(camera)
            got.append((frame.image.copy(), frame.hits.copy(), renderer.render(camera, hits=False).image))
            del frame
        tiles = renderer.tracer.traces_rows
        if tiles:
            rows = [renderer.render(c, rows=(8, height)) for c in cameras]
    options = {"adapter": request.getfixturevalue("adapter")} if device == "wgpu" else {}
    with raybench.backends.tracer(device, scene.spheres, width, height, accel=accel, **options) as tracer:
        for i, (camera, (image, hits, image_no_hits)) in enumerate(zip(cameras, got)):
            want_image, want_hits = (a.copy() for a in tracer.trace(camera.basis(width, height)))
            np.testing.assert_array_equal(image, want_image)
            np.testing.assert_array_equal(hits, want_hits)
            np.testing.assert_array_equal(image_no_hits, want_image)
            if tiles:
                np.testing.assert_array_equal(rows[i].image, want_image[8:])
                np.testing.assert_array_equal(rows[i].hits, want_hits[8:])
