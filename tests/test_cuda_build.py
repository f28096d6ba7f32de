"""The BVH built on the GPU (backends.cuda.build): a valid tree in the layout
every walk reads, its sort checked against NumPy's, and walks through it that
give the brute force's hits. Under numba's simulator where there is no GPU
(scenes of tens of spheres: every simulated thread is a Python thread)."""

import numpy as np
import pytest
from gpu_trees import morton_reference, tree_model
from scenes import IN_VIEW, SCENES
from test_bvh import brute, check_tree

import raybench
from raybench import bvh, layout
from raybench.backends import cuda as cuda_backend
from raybench.backends import options as device_options
from raybench.bvh import lbvh
from raybench.bvh.cost import sah_cost

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off"),
]


def sim() -> bool:
    return cuda_backend.simulated()


def small(rng) -> int:
    return int(rng.integers(2, 33 if sim() else 5000))


def gpu_tree(spheres, leaf_size=None, quality=None, **options):
    from numba import cuda

    from raybench.backends.cuda import build as cuda_build

    n = spheres.shape[1]
    given = (leaf_size is not None or quality is not None) and n >= 2
    builder = cuda_build.Builder(n, leaf_size, quality) if given else None
    return cuda_build.build(spheres, cuda.to_device(spheres), builder, **options)


@pytest.mark.parametrize("kind", ["generated", "cloud", "one_point", "duplicates", "line", "chain"])
def test_gpu_tree_is_valid(rng, kind):
    """Every sphere in one leaf, each box around its spheres' padded boxes
    and inside its parent's, the depth reported being the tree's; leaves of
    up to leaf_size spheres, and none of more."""
    scene, _ = SCENES[kind](rng, small(rng))
    leaf_size = int(rng.integers(1, bvh.LEAF_MAX + 1))
    tree = gpu_tree(scene.spheres, leaf_size, str(rng.choice(["sah", "lbvh"])))
    assert tree.built_on == ("gpu" if len(scene) >= 2 else "host")
    host = tree.to_host()
    check_tree(host, scene.spheres)
    assert tree.node_count == max(len(scene) - 1, 1)  # Karras's internal nodes, collapsed ones kept
    counts = host.links[:, layout.COUNT : layout.COUNT + 2]
    assert counts.max() <= leaf_size


@pytest.mark.parametrize("kind", ["generated", "overlapping", "one_point", "duplicates", "line"])
def test_model_gives_the_kernels_tree(rng, kind):
    """raybench.bvh.lbvh_model, with which benchmarks/archive/gpu_tree_model.py
    measures the GPU trees' SAH cost at sizes the simulator cannot build,
    gives the kernels' tree: every row
    (collapsed ones too), the order, the depth, the rows reached and the
    device's cost, bit for bit under the simulator. A GPU may fuse
    multiply-adds, which can tip a choice between two costs equal to the
    last bit (a leaf or a row, a treelet's split): there the same cost
    within rounding."""
    from raybench.backends.cuda import build as cuda_build

    model = tree_model()
    scene, _ = SCENES[kind](rng, max(small(rng), 2))
    quality = str(rng.choice(cuda_build.QUALITIES))
    leaf_size = int(rng.integers(1, bvh.LEAF_MAX + 1))
    tree = gpu_tree(scene.spheres, leaf_size, quality)
    nodes, order, ordered, depth, rows, cost = model.build(scene.spheres, quality, leaf_size)
    got = tree.to_host()
    if not sim():
        assert sah_cost(got.nodes) == pytest.approx(sah_cost(nodes), rel=1e-4)
        return
    assert np.array_equal(got.order, order) and np.array_equal(got.ordered, ordered)
    assert depth == tree.depth
    assert np.array_equal(got.nodes.view(np.uint32), nodes.view(np.uint32))
    from numba import cuda

    builder = cuda_build.Builder(len(scene), leaf_size, quality)
    builder.launch_build(cuda.to_device(scene.spheres))
    assert builder.read_rows() == rows
    assert builder.read_cost() == cost


def test_sah_leaves_are_the_cheapest_cut(rng):
    """The "sah" leaves cut the LBVH where the SAH is least: its cost is no
    more than that of any fixed leaf size up to the same most ("lbvh"
    leaves: the same rows, cut elsewhere), and than a cut with no leaf of
    more than one sphere."""
    from raybench.backends.cuda import build as cuda_build

    scene, _ = SCENES[str(rng.choice(["generated", "overlapping", "cloud"]))](rng, int(rng.integers(12, 33)))
    best = sah_cost(gpu_tree(scene.spheres, bvh.LEAF_MAX, "sah").to_host().nodes)
    for size in range(1, bvh.LEAF_MAX + 1):
        fixed = gpu_tree(scene.spheres, size, "lbvh").to_host()
        assert best <= sah_cost(fixed.nodes) * (1 + 1e-5)
    with pytest.raises(ValueError, match="quality: must be one of sah, treelet, lbvh, got 'best'"):
        cuda_build.Builder(4, quality="best")


@pytest.mark.parametrize("kind", ["generated", "cloud", "line", "duplicates"])
def test_treelets_lower_the_cost_and_keep_leaves_ranges(rng, kind):
    """The "treelet" tree, after 1 to 3 passes: valid (every sphere in one
    leaf of consecutive spheres, boxes nested, the depth its own), its rows'
    links up leading back to the root (refits climb them), no costlier than
    the "sah" tree of the same LBVH, and after a refit to the same spheres
    the same tree; the model's tree."""
    from numba import cuda

    from raybench.backends.cuda import build as cuda_build

    passes = int(rng.integers(1, 4))
    scene, _ = SCENES[kind](rng, int(rng.integers(12, 33)))
    sah = sah_cost(gpu_tree(scene.spheres, quality="sah").to_host().nodes)
    builder = cuda_build.Builder(len(scene), quality="treelet", treelet_passes=passes)
    d_spheres = cuda.to_device(scene.spheres)
    builder.launch_build(d_spheres)
    tree = builder.tree(builder.read_depth(), 0.0).to_host()
    check_tree(tree, scene.spheres)
    assert sah_cost(tree.nodes) <= sah * (1 + 1e-5)
    assert builder.read_cost() == pytest.approx(sah_cost(tree.nodes), rel=1e-5)
    up = builder.up.copy_to_host()
    leaf_up = builder.leaf_up.copy_to_host()
    for link in leaf_up:
        seen = 0
        while link >= 0:  # every sphere's way up ends at the root, in at most every row
            link = up[link // 2]
            seen += 1
            assert seen <= len(scene)
    builder.launch_refit(d_spheres)
    again = builder.tree(builder.read_depth(), 0.0).to_host()
    assert np.array_equal(again.nodes.view(np.uint32), tree.nodes.view(np.uint32))
    if sim():  # on a GPU, fused multiply-adds may tip near ties (test_model_gives_the_kernels_tree)
        nodes, order, _ordered, depth, _rows, _cost = tree_model().build(scene.spheres, "treelet", passes=passes)
        assert np.array_equal(tree.order, order) and depth == tree.depth
        assert np.array_equal(tree.links[:, layout.REF :], nodes.view(np.int32)[:, layout.REF :])


def test_sort_is_stable_by_morton_code(rng):
    """The leaf order is the spheres sorted by their Morton codes, equal codes
    in index order: NumPy's stable argsort of the reference codes. Codes
    made to collide often (centres on a coarse grid)."""
    from numba import cuda

    from raybench.backends.cuda import build as cuda_build

    n = small(rng)
    scene, _ = SCENES["generated"](rng, n)
    spheres = scene.spheres.copy()
    spheres[:3] = np.round(spheres[:3] * rng.uniform(0.5, 4)) / 2  # many shared cells
    builder = cuda_build.Builder(n)
    builder.launch_build(cuda.to_device(spheres))
    want = np.argsort(morton_reference(spheres), kind="stable")
    assert np.array_equal(builder.order.copy_to_host(), want)
    keys = builder.keys[cuda_build.PASSES % 2].copy_to_host()
    assert np.array_equal(keys, morton_reference(spheres)[want])


def test_one_point_is_log2_deep(rng):
    """All centres equal: one Morton code, told apart by place alone; the
    tree over the places is balanced."""
    n = small(rng)
    scene, _ = SCENES["one_point"](rng, n)
    tree = gpu_tree(scene.spheres, leaf_size=1)
    assert tree.depth == int(np.ceil(np.log2(n)))
    check_tree(tree.to_host(), scene.spheres)


def test_too_deep_falls_back_to_the_host_build(rng):
    """A tree deeper than the walks' stack allows is replaced by the host's,
    whose depth is bounded (here the bound made small: no scene the
    simulator can build is 48 deep)."""
    scene, _ = SCENES["generated"](rng, int(rng.integers(10, 24)))
    deep = gpu_tree(scene.spheres)
    tree = gpu_tree(scene.spheres, max_depth=deep.depth - 1)
    assert tree.built_on == "host"
    host = bvh.build(scene.spheres)
    got = tree.to_host()
    assert np.array_equal(got.links, host.links) and np.array_equal(got.order, host.order)


@pytest.mark.parametrize(
    "kind", ["generated", "inside", "overlapping", "one_point", "duplicates", "line", "one", "none"]
)
def test_gpu_tree_walks_give_the_brute_force(rng, kind):
    """Both walks on the GPU's tree (of any quality): the brute force's hits,
    bit for bit under the simulator, within rounding on a GPU (its compiler
    may fuse multiply-adds; test_bvh's CUDA test says the same)."""
    quality = str(rng.choice(lbvh.QUALITIES))
    scene, camera = SCENES[kind](rng, small(rng))
    width, height = (19, 13) if sim() else (643, 401)
    walk = str(rng.choice(device_options.WALKS))
    gpu = raybench.render(
        scene, camera, width, height, device="cuda", build="gpu", quality=quality, walk=walk, block=(8, 4)
    )
    cpu = brute(scene, camera, width, height)
    if sim():
        assert np.array_equal(gpu.hits, cpu.hits) and np.array_equal(gpu.image, cpu.image)
    else:
        assert (gpu.hits != cpu.hits).mean() < 1e-3
    if kind in ("one_point", "one") or (kind in IN_VIEW and len(scene) >= 100):  # not vacuous: a hit
        assert (cpu.hits >= 0).any()


def test_sphere_prefix_builds_its_own_tree_on_the_gpu(rng):
    """A frame of the first `count` spheres (the viewer's live count), its
    tree built on the GPU from the spheres already there."""
    scene, camera = SCENES["generated"](rng, 30)
    with raybench.backends.tracer("cuda", scene.spheres, 19, 13, build="gpu") as tracer:
        for count in (int(rng.integers(2, 29)), 1, 0):
            tracer.trace(camera.basis(19, 13), count)
            want = brute(scene.head(count), camera, 19, 13)
            assert tracer.bvh.count == count
            assert np.array_equal(tracer.hits, want.hits) and np.array_equal(tracer.image, want.image)


@pytest.mark.parametrize(
    "options,match",
    [
        ({"build": "sideways"}, "build: must be one of host, gpu, got 'sideways'"),
        ({"build": "gpu", "accel": "none"}, "build: applies to the BVH only"),
    ],
)
def test_bad_build_options(options, match):
    with pytest.raises(raybench.RaybenchError, match=match):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cuda", **options)


def test_build_is_an_option_of_cuda_only():
    with pytest.raises(raybench.RaybenchError, match="option 'build' does not apply to device cpu"):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cpu", build="host")


def test_sah_cost_of_a_tree_by_hand():
    """sah_cost against a tree worked out by hand. Row 0: a leaf of
    2 spheres in [0,1]^3 and a row in [2,3]x[0,1]x[0,1]; row 1: a leaf of 1
    in [2,3]x[0,1]x[0,0.5] and an empty child. Half areas (dx dy + dy dz +
    dz dx): root 7, leaf 3, row 1 2, its leaf 2; so (2 * 7 + 2 * 3 + 2 * 2 +
    1 * 2) / 7 with a node costing 2 sphere tests."""
    nodes = np.zeros((2, layout.NODE_FLOATS), np.float32)
    links = nodes.view(np.int32)
    nodes[0, 0:6] = [0, 0, 0, 1, 1, 1]
    nodes[0, 6:12] = [2, 0, 0, 3, 1, 1]
    links[0, layout.REF : layout.REF + 2] = [0, 1]
    links[0, layout.COUNT : layout.COUNT + 2] = [2, layout.INNER]
    nodes[1, 0:6] = [2, 0, 0, 3, 1, 0.5]
    nodes[1, 6:9], nodes[1, 9:12] = layout.EMPTY, -layout.EMPTY
    links[1, layout.REF : layout.REF + 2] = [2, 3]
    links[1, layout.COUNT : layout.COUNT + 2] = [1, 0]
    assert sah_cost(nodes) == pytest.approx(26 / 7)
    # a row no walk reaches (cuda_build leaves collapsed subtrees' rows) adds nothing
    dead = np.concatenate([nodes, nodes[:1] * 100])
    assert sah_cost(dead) == pytest.approx(26 / 7)


# --- spheres that move: refit, or rebuild ------------------------------------


def moved(rng, spheres, scale):
    """The spheres with their centres moved by up to scale radii."""
    out = spheres.copy()
    out[:3] += (rng.uniform(-1, 1, (3, spheres.shape[1])) * spheres[3] * scale).astype(np.float32)
    return out


def test_device_sah_cost_is_tree_costs(rng):
    """Builder.read_cost, summed on the device over the rows a walk reaches,
    against sah_cost on the tree copied back: fresh, then refitted
    to moved spheres."""
    from numba import cuda

    from raybench.backends.cuda import build as cuda_build

    scene, _ = SCENES["generated"](rng, small(rng))
    builder = cuda_build.Builder(len(scene), int(rng.integers(1, 5)))
    d_spheres = cuda.to_device(scene.spheres)
    builder.launch_build(d_spheres)
    tree = builder.tree(builder.read_depth(), 0.0)
    assert builder.read_cost() == pytest.approx(sah_cost(tree.to_host().nodes), rel=1e-5)
    spheres = moved(rng, scene.spheres, 3.0)
    d_spheres.copy_to_device(spheres)
    builder.launch_refit(d_spheres)
    refitted = tree.to_host()
    check_tree(refitted, spheres)
    assert builder.read_cost() == pytest.approx(sah_cost(refitted.nodes), rel=1e-5)


@pytest.mark.parametrize("limit,want", [(np.inf, "refit"), (0.0, "build")])
def test_update_refits_within_the_limit_and_rebuilds_past_it(rng, limit, want):
    """Tracer.update: a refit keeps the tree's rows (its links), a rebuild
    makes new ones; either way the frame is the brute force's of the moved
    spheres."""
    quality = str(rng.choice(lbvh.QUALITIES))
    scene, camera = SCENES["generated"](rng, int(rng.integers(10, 30)))
    with raybench.backends.tracer(
        "cuda", scene.spheres, 19, 13, build="gpu", quality=quality, refit_limit=limit
    ) as tracer:
        before = tracer.d_links.copy_to_host()[:, layout.REF :]  # the rows' links, not their boxes
        spheres = moved(rng, scene.spheres, 2.0)
        assert tracer.update(spheres) == want
        assert tracer.build_s > 0
        tracer.trace(camera.basis(19, 13))
        if want == "refit":
            assert np.array_equal(tracer.d_links.copy_to_host()[:, layout.REF :], before)
        want_frame = brute(raybench.Scene(spheres[:3].T, spheres[3], spheres[4:].T), camera, 19, 13)
        assert np.array_equal(tracer.hits, want_frame.hits) and np.array_equal(tracer.image, want_frame.image)


def test_update_of_a_host_tree_rebuilds_it_and_checks_its_input(rng):
    scene, camera = SCENES["generated"](rng, 30)
    with raybench.backends.tracer("cuda", scene.spheres, 19, 13, build="host") as tracer:
        spheres = moved(rng, scene.spheres, 2.0)
        assert tracer.update(spheres) == "build"
        tracer.trace(camera.basis(19, 13))
        want = brute(raybench.Scene(spheres[:3].T, spheres[3], spheres[4:].T), camera, 19, 13)
        assert np.array_equal(tracer.hits, want.hits)
        with pytest.raises(raybench.RaybenchError, match=r"update: spheres must be a \(7, 30\) float32 array"):
            tracer.update(spheres[:, :10])


def test_walk_is_chosen_by_the_rows_a_walk_reaches(rng):
    """The GPU's tree keeps its collapsed subtrees' rows; the walk's choice
    (cuda.choose_walk, by the tree's bytes) counts only those a walk reaches
    from the root, counted here on the tree copied back."""
    scene, _ = SCENES["generated"](rng, small(rng))
    with raybench.backends.tracer("cuda", scene.spheres, 8, 8, build="gpu") as tracer:
        host = tracer.bvh.to_host()
        reached, todo = 0, [0]
        while todo:
            row = todo.pop()
            reached += 1
            for slot in range(2):
                if host.links[row, layout.COUNT + slot] == layout.INNER:
                    todo.append(int(host.links[row, layout.REF + slot]))
        assert tracer._rows_walked() == reached
