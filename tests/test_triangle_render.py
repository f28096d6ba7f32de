"""Triangle meshes rendered on the cpu, through the BVH, held to a float64
renderer written here: Moller-Trumbore over every triangle per pixel, the
nearest hit, then the thesis's shading (colour - (1 - cos)) or Whitted's
one default light on a convex mesh (ambient plus Lambert, no shadow a
convex mesh can cast on its own lit faces). Also: no ray slips between a
closed mesh's triangles, both CPU walks give the same frame, brute force
too, and `raybench render --scene FILE.ply` end to end."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image

from raybench import Camera, RaybenchError, Renderer, backends, render
from raybench.cli import run
from raybench.kernels import footprint
from raybench.layout import TRI_RED
from raybench.lighting import DEFAULT_AMBIENT
from raybench.mesh_render import mesh_scene, recoloured
from raybench.meshes import Mesh

W, H = 64, 48


def mesh_of(shape) -> Mesh:
    return Mesh(np.asarray(shape.vertices, np.float32), np.asarray(shape.faces, np.int32))


def icosphere() -> Mesh:
    return mesh_of(trimesh.creation.icosphere(subdivisions=2))


def box() -> Mesh:
    # turned, so that its faces and edges meet the rays at no special angle
    turn = trimesh.transformations.euler_matrix(0.4, 0.7, 0.2)
    return mesh_of(trimesh.creation.box(extents=(1.0, 1.4, 0.8), transform=turn))


def rays64(camera: Camera, width: int = W, height: int = H):
    """Each pixel's primary ray in float64 from the camera's float32 basis
    (trace.primary_ray's formula): origin (3,), directions (H * W, 3)."""
    basis = camera.basis(width, height).astype(np.float64)
    xs, ys = np.meshgrid(np.arange(width), np.arange(height))
    u = (xs.ravel() + 0.5) / width - 0.5
    v = 0.5 - (ys.ravel() + 0.5) / height
    d = basis[1] + np.outer(u, basis[2]) + np.outer(v, basis[3])
    return basis[0], d / np.linalg.norm(d, axis=1, keepdims=True)


def reference(leaves: np.ndarray, origin, dirs):
    """Moller-Trumbore in float64 over every triangle: for each ray the
    nearest triangle hit (-1 for none), its t, the plane's unit normal, and
    how far inside the triangle the ray passes (its smallest barycentric
    weight; negative outside) for the nearest hit, or for a miss the largest
    over the triangles ahead (how near to an edge it passed)."""
    v = leaves[:9].astype(np.float64).T.reshape(-1, 3, 3)
    a, e1, e2 = v[:, 0], v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    normal = np.cross(e1, e2)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    p = np.cross(dirs[:, None, :], e2[None])  # (R, F, 3)
    det = np.einsum("fk,rfk->rf", e1, p)
    s = origin - a  # (F, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        bu = np.einsum("fk,rfk->rf", s, p) / det
        q = np.cross(s, e1)  # (F, 3)
        bv = np.einsum("rk,fk->rf", dirs, q) / det
        t = np.einsum("fk,fk->f", e2, q)[None] / det
    inside = np.minimum(np.minimum(bu, bv), 1 - bu - bv)
    ahead = np.isfinite(t) & (t > 1e-9)
    hit = ahead & (inside >= 0)
    t_hit = np.where(hit, t, np.inf)
    nearest = np.argmin(t_hit, axis=1)
    rows = np.arange(len(dirs))
    got = np.isfinite(t_hit[rows, nearest])
    index = np.where(got, nearest, -1)
    margin = np.where(got, inside[rows, nearest], np.where(ahead, inside, -np.inf).max(axis=1))
    return index, t_hit[rows, nearest], normal[nearest], margin


def to_bytes(c):
    return np.floor(np.clip(c, 0, 1) * 255 + 0.5).astype(int)


def thesis_image(leaves, index, normal, dirs, width=W, height=H):
    """The thesis's picture in float64: colour - (1 - |n.D|) where a ray hits,
    the gradient (x / 1024, y / 1024, x / 786) where none does."""
    colour = leaves[TRI_RED : TRI_RED + 3, np.maximum(index, 0)].T.astype(np.float64)
    cos = np.abs(np.einsum("rk,rk->r", normal, dirs))
    hit = colour - (1 - cos)[:, None]
    xs, ys = np.meshgrid(np.arange(width), np.arange(height))
    x, y = xs.ravel().astype(np.float64), ys.ravel().astype(np.float64)
    miss = np.stack([x / 1024, y / 1024, x / 786], axis=1)
    return to_bytes(np.where((index >= 0)[:, None], hit, miss)).reshape(height, width, 3)


def check_against_reference(frame, leaves, index, margin, expected):
    """The frame's hits are the reference's wherever the ray passes clear of
    an edge; every disagreement is a ray within a hair of one (a silhouette,
    or an edge two triangles share); and at least 99.5% of the pixels are
    within one 8-bit step."""
    hits = frame.hits.ravel()
    differ = hits != index
    assert np.all(np.abs(margin[differ]) < 1e-4), margin[differ]
    close = (np.abs(frame.image.astype(int) - expected) <= 1).all(axis=2)
    assert close.mean() >= 0.995, close.mean()
    return differ


@pytest.fixture(scope="module", params=["icosphere", "box"])
def outside(request):
    """A mesh seen from the camera fitted to it, and the reference's answer."""
    scene = mesh_scene({"icosphere": icosphere, "box": box}[request.param]())
    origin, dirs = rays64(scene.camera)
    index, _t, normal, margin = reference(scene.triangles, origin, dirs)
    return scene, dirs, index, normal, margin


def test_thesis_frame_is_the_float64_reference(outside):
    """(a) The 4-wide packets through the tree: the reference's hits and
    colours."""
    scene, dirs, index, normal, margin = outside
    frame = render(scene, None, W, H, device="cpu", threads=2)
    assert 0.2 < (frame.hits >= 0).mean() < 0.9  # the mesh is in the picture, and so is the background
    check_against_reference(frame, scene.triangles, index, margin, thesis_image(scene.triangles, index, normal, dirs))


def test_no_ray_slips_through_a_closed_mesh(outside):
    """(b) Watertight: every ray the reference sees pass well inside the
    mesh's outline hits a triangle; from inside, every ray hits."""
    scene, _dirs, index, _normal, margin = outside
    frame = render(scene, None, W, H, device="cpu", threads=2)
    well_inside = (index >= 0) & (margin > 1e-3)
    assert (frame.hits.ravel()[well_inside] >= 0).all()
    views = ((0.01, 0.02, -0.03), (0.3, 0.2, 1.0), 100.0), ((0, 0, 0), (1, 1, 1), 120.0)
    for camera in (Camera(position, look_at, fov_deg=fov) for position, look_at, fov in views):
        inside = render(scene, camera, W, H, device="cpu", threads=2)
        assert (inside.hits >= 0).all(), (inside.hits < 0).sum()


def test_both_cpu_walks_and_brute_force_give_one_frame(outside):
    """(c) The binary tree's walk a ray at a time (tree_width 2), the
    4-wide packets and the brute-force scan: the same hits and bytes."""
    scene = outside[0]
    wide = render(scene, None, W, H, device="cpu", threads=2, tree_width=4)
    binary = render(scene, None, W, H, device="cpu", threads=2, tree_width=2)
    brute = render(scene, None, W, H, device="cpu", threads=2, accel="none", kernel="simple")
    for other in (binary, brute):
        assert (other.hits == wide.hits).all() and (other.image == wide.image).all()
    # seen along a diagonal, from inside: packets whose rays go fastest along different axes, which
    # the packets' leaf tests turn a triangle for a ray at a time (packets._aimed_tests)
    diagonal = Camera((0.01, 0.02, -0.03), (1.0, 1.0, 1.0), fov_deg=120.0)
    wide = render(scene, diagonal, W, H, device="cpu", threads=2, tree_width=4)
    binary = render(scene, diagonal, W, H, device="cpu", threads=2, tree_width=2)
    assert (binary.hits == wide.hits).all() and (binary.image == wide.image).all()
    # unless told (options.KIND_TREE_WIDTH), a mesh's primary rays go as packets through the
    # 4-wide tree, under Whitted shading too (its shadow rays and bounces through it alone)
    with backends.tracer("cpu", scene.triangles, W, H, primitive="triangle", threads=2) as tracer:
        assert tracer.tree_width == 4
    with Renderer(scene, W, H, device="cpu", shading="whitted", threads=2) as renderer:
        assert renderer.tracer.tree_width == 4


@pytest.mark.slow
def test_whitted_frame_is_the_float64_reference():
    """Whitted shading of a convex mesh under its default light: ambient
    plus Lambert's cosine, colour times (ambient + max(n.L, 0)), no shadow
    (a convex mesh shades none of its lit faces), the normal turned to the
    viewer; the packets and the binary tree alike."""
    scene = recoloured(mesh_scene(icosphere()), (0.9, 0.6, 0.3))
    origin, dirs = rays64(scene.camera)
    index, t, normal, margin = reference(scene.triangles, origin, dirs)
    point = origin + np.where(index >= 0, t, 0)[:, None] * dirs  # misses at the origin: unused, and finite
    n = normal * -np.sign(np.einsum("rk,rk->r", normal, dirs))[:, None]
    to_light = np.asarray(scene.lights[0].position) - point
    facing = np.maximum(np.einsum("rk,rk->r", n, to_light / np.linalg.norm(to_light, axis=1, keepdims=True)), 0)
    colour = scene.triangles[TRI_RED : TRI_RED + 3, np.maximum(index, 0)].T.astype(np.float64)
    lit = colour * (np.asarray(DEFAULT_AMBIENT) + facing[:, None])
    xs, ys = np.meshgrid(np.arange(W), np.arange(H))
    miss = np.stack([xs.ravel() / 1024, ys.ravel() / 1024, xs.ravel() / 786], axis=1)
    expected = to_bytes(np.where((index >= 0)[:, None], lit, miss)).reshape(H, W, 3)
    frames = [render(scene, None, W, H, device="cpu", shading="whitted", threads=2, tree_width=w) for w in (4, 2)]
    check_against_reference(frames[0], scene.triangles, index, margin, expected)
    assert (frames[0].image == frames[1].image).all() and (frames[0].hits == frames[1].hits).all()
    assert frames[0].rays["shadow"] > 0 and frames[0].rays["reflection"] == 0


def test_the_fast_kernel_refuses_triangles_in_one_line():
    """Every device traces triangles (test_triangle_cuda.py, test_triangle_wgpu.py); the fast
    brute-force kernel culls spheres only; a buffer without colour rows is not a mesh's."""
    leaves = mesh_scene(icosphere()).triangles
    with pytest.raises(RaybenchError, match="kernel 'fast'"):
        backends.tracer("cpu", leaves, W, H, primitive="triangle", accel="none", kernel="fast")
    with pytest.raises(RaybenchError, match="at least 12 rows"):
        backends.tracer("cpu", np.ascontiguousarray(leaves[:9]), W, H, primitive="triangle")
    with pytest.raises(RaybenchError, match="primitive"):
        backends.tracer("cpu", leaves, W, H, primitive="cone")


def cli(capsys, *args):
    code = run([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_render_a_ply_file_end_to_end(capsys, tmp_path):
    """(e) raybench render --scene FILE.ply: a PNG of the mesh, the same
    pixels as render()'s of the file's triangles in the --color given;
    Whitted's default light said in a note."""
    path = tmp_path / "ball.ply"
    trimesh.creation.icosphere(subdivisions=1).export(path)
    out = tmp_path / "ball.png"
    code, stdout, err = cli(capsys, "render", "--scene", path, "--size", f"{W}x{H}", "--device", "cpu",
                            "--color", "0.2,0.5,0.9", "-o", out)  # fmt: skip
    assert code == 0, err
    assert "80 triangles" in stdout and "cpu" in stdout
    image = np.asarray(Image.open(out).convert("RGB"))
    from raybench.meshes import load_mesh

    expected = render(recoloured(mesh_scene(load_mesh(path)), (0.2, 0.5, 0.9)), None, W, H, device="cpu", threads=2)
    assert (image == expected.image).all()
    code, stdout, err = cli(capsys, "render", "--scene", path, "--size", f"{W}x{H}", "--shading", "whitted",
                            "-o", out)  # fmt: skip
    assert code == 0, err
    assert "a mesh file has no lights or materials" in stdout


@pytest.mark.parametrize(
    "name, content, args, needle",
    [
        ("bad.ply", b"ply\nnot a header\n", (), "bad.ply: "),
        ("none.obj", None, (), "no such file"),
        ("ok.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ("--color", "2,0,0"), "--color"),
        ("ok.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ("--device", "wgpu"), ""),
        ("ok.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ("--path", "orbit"), "--path"),
    ],
)
def test_bad_mesh_files_and_options_are_one_line(capsys, tmp_path, name, content, args, needle):
    """(e) A file trimesh cannot read, a missing one, a colour out of range,
    a GPU, a sequence: exit 2 and one line, no traceback."""
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    code, _stdout, err = cli(capsys, "render", "--scene", path, "--size", "16x8", "-o", tmp_path / "x.png", *args)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err and needle in err, err


def test_other_commands_refuse_a_mesh_in_one_line(capsys, tmp_path):
    path = tmp_path / "tri.obj"
    path.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code, _stdout, err = cli(capsys, "scene", "nff", "--scene", path, "-o", tmp_path / "tri.nff")
    assert code == 2 and "render and view only so far" in err and err.count("\n") == 1, err
    assert not (tmp_path / "tri.nff").exists()


def test_packets_outside_the_trees_footprint_are_the_background():
    """The cpu's packets colour a packet outside the tree's footprint on the
    frame (footprint.tree_window) the background's without making its rays:
    the same bytes and hits as brute force, which makes every ray, for a
    mesh in a corner of the frame, partly off it, behind the camera, and
    round the camera; and the footprint of a mesh in a corner really is a
    part of the frame, so the packets there are not made."""
    scene = mesh_scene(icosphere())
    views = (
        ((0.0, 0.0, -6.0), (1.5, 1.0, 0.0), 40.0),  # the mesh in a corner
        ((0.0, 0.0, -4.0), (2.2, 0.0, 0.0), 35.0),  # partly off the frame's edge
        ((0.0, 0.0, -3.0), (0.0, 0.0, -6.0), 60.0),  # behind the camera
        ((0.0, 0.0, 0.9), (0.0, 0.0, 5.0), 150.0),  # inside the box: the camera's plane cuts it
    )
    for position, look_at, fov in views:
        camera = Camera(position, look_at, fov_deg=fov)
        wide = render(scene, camera, W, H, device="cpu", threads=2, tree_width=4)
        brute = render(scene, camera, W, H, device="cpu", threads=2, accel="none", kernel="simple")
        assert (brute.hits == wide.hits).all() and (brute.image == wide.image).all(), (position, look_at)
        if fov < 60:  # the mesh in part of the frame
            assert 0 < (wide.hits >= 0).mean() < 0.5
    corner = Camera(*views[0][:2], fov_deg=views[0][2])
    with backends.tracer("cpu", scene.triangles, W, H, primitive="triangle", threads=2) as tracer:
        basis = corner.basis(W, H)
        ox, oy, oz = (np.float32(v) for v in basis[0])
        margin = (abs(ox) + abs(oy) + abs(oz)) * np.float32(2.0**-16)
        view = footprint.frame_view(basis, W, H)
        rows = footprint.tree_window(view, tracer.wide, tracer.wide.view(np.int32), (0, 0, W - 1, H - 1), H, W,
                                     margin, ox, oy, oz)  # fmt: skip
    first, end, first_column, end_column = rows
    assert 0 < (end - first) * (end_column - first_column) < W * H / 2, rows
