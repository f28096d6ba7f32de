"""The BVH: its builder's tree, and the walk through it, which must give
exactly the brute-force picture and hit indices (the brute-force kernels are
held to the float64 reference by test_cpu and test_fast)."""

import dataclasses

import numpy as np
import pytest
from scenes import IN_VIEW, KINDS, SCENES, chain, one_point

import raybench
from raybench import Scene, bvh, compiled, kernels, layout
from raybench.backends import cuda as cuda_backend
from raybench.backends import options as device_options
from raybench.bvh import oneshot, pages, sah_steps, sah_wide
from raybench.kernels import packet_boxes, packets
from raybench.kernels.primitives import sphere

# The algorithm as plain Python on NumPy float32 scalars, run without a compiler.
K = kernels.make(lambda f: f)


def brute(scene, camera, width, height):
    return raybench.render(scene, camera, width, height, device="cpu", accel="none", kernel="simple")


# --- the walk gives the brute-force picture ----------------------------------


@pytest.fixture(params=[2, 4], ids=["binary", "wide"])
def tree_width(request):
    """The CPU packets' tree: the binary one, and the same collapsed into 4-wide nodes."""
    return request.param


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_cpu_bvh_equals_brute_force(rng, kind, tree_width):
    n = int(rng.integers(1, 400 if tree_width == 2 else 3000))
    scene, camera = SCENES[kind](rng, n)
    width, height = int(rng.integers(20, 60)), int(rng.integers(10, 40))
    want = brute(scene, camera, width, height)
    got = raybench.render(scene, camera, width, height, device="cpu", accel="bvh", threads=3, tree_width=tree_width)
    assert np.array_equal(got.hits, want.hits), (got.hits != want.hits).sum()
    assert np.array_equal(got.image, want.image)
    if kind in IN_VIEW and n >= 100:  # not vacuous: something was hit (a few spheres may all be out of view)
        assert (want.hits >= 0).any()


@pytest.mark.parametrize("size", [(1, 1), (1, 5), (9, 3), (33, 7), (17, 70), (47, 21)])
def test_cpu_packets_at_the_edges(rng, size, tree_width):
    """The CPU walks packets of cpu.PACKET_W x PACKET_H rays: images and
    chunks of rows that are no whole number of packets, and more threads
    than rows."""
    scene, camera = KINDS["generated"](rng, int(rng.integers(50, 300)))
    want = brute(scene, camera, *size)
    got = raybench.render(scene, camera, *size, device="cpu", threads=int(rng.integers(1, 9)), tree_width=tree_width)
    assert np.array_equal(got.hits, want.hits) and np.array_equal(got.image, want.image)


def test_ties_go_to_the_smaller_index(rng, tree_width):
    """Identical spheres: brute force shows the first; so must the walk."""
    scene, camera = one_point(rng, 64)
    s = scene.spheres.copy()
    s[3] = 1.5
    same = Scene(s[0:3].T, s[3], s[4:7].T)
    frame = raybench.render(same, camera, 24, 16, device="cpu", tree_width=tree_width)
    assert set(np.unique(frame.hits)) <= {-1, 0} and (frame.hits == 0).any()


def test_tree_width_is_an_option_of_the_bvh_packets(rng):
    """tree_width picks the CPU packets' tree; it means nothing to brute force
    or to Whitted's walk, and only 2 and 4 are built."""
    spheres = raybench.random_spheres(5, int(rng.integers(2**31))).spheres
    for options, message in (
        ({"accel": "none", "tree_width": 2}, "tree_width: applies to the BVH's packets only"),
        ({"tree_width": 3}, "tree_width: must be one of 2, 4, got 3"),
    ):
        with pytest.raises(raybench.RaybenchError, match=message):
            raybench.backends.tracer("cpu", spheres, 8, 8, **options)
    with pytest.raises(raybench.RaybenchError, match="option 'tree_width' does not apply to device cuda"):
        raybench.backends.tracer("cuda", spheres, 8, 8, tree_width=2)


def test_sphere_prefix_builds_its_own_tree(rng):
    """A frame of the first `count` spheres (the viewer's live count)."""
    scene, camera = KINDS["cloud"](rng, 120)
    tracer = raybench.backends.tracer("cpu", scene.spheres, 40, 24)
    try:
        for count in (37, len(scene), 0):
            tracer.trace(camera.basis(40, 24), count)
            want = brute(scene.head(count), camera, 40, 24)
            assert np.array_equal(tracer.hits, want.hits) and np.array_equal(tracer.image, want.image)
    finally:
        tracer.close()


@pytest.mark.slow
@pytest.mark.gpu
@pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off")
@pytest.mark.parametrize("walk", device_options.WALKS)
@pytest.mark.parametrize("kind", ["generated", "inside", "one_point", "duplicates", "line", "none"])
def test_cuda_bvh_equals_brute_force(rng, kind, walk):
    """The walks compiled for CUDA: bit for bit under the simulator, within
    rounding on a GPU (its compiler may fuse multiply-adds). The frame is no
    multiple of the block, so packets have rays off the image."""
    sim = cuda_backend.simulated()
    scene, camera = SCENES[kind](rng, int(rng.integers(1, 40 if sim else 5000)))
    width, height = (19, 13) if sim else (643, 401)
    gpu = raybench.render(scene, camera, width, height, device="cuda", block=(8, 4), walk=walk)
    cpu = brute(scene, camera, width, height)
    if sim:
        assert np.array_equal(gpu.hits, cpu.hits) and np.array_equal(gpu.image, cpu.image)
    else:
        assert (gpu.hits != cpu.hits).mean() < 1e-3
        same = gpu.hits == cpu.hits
        assert np.abs(gpu.image.astype(int) - cpu.image.astype(int))[same].max(initial=0) <= 1


# --- the box test never loses a hit -------------------------------------------


def tangent_pairs(rng, n):
    """Rays that graze a sphere where it touches its box (the extreme point
    along an axis), within ~1e-7 of its radius: the exact float32 test
    accepts about half of them, and an unpadded box test would reject those
    just outside the box's face. Radii 1e-3 to 1e3; origins 1 to 1e5 away,
    anywhere from the scene's origin."""
    out = []
    for _ in range(n):
        c = rng.uniform(-1, 1, 3) * 10.0 ** rng.uniform(-1, 4)
        r = 10.0 ** rng.uniform(-3, 3)
        a = int(rng.integers(3))
        sign = rng.choice([-1.0, 1.0])
        touch = c.copy()
        touch[a] += sign * r * (1 + rng.uniform(-2e-7, 2e-7))
        d = rng.normal(size=3)
        d[a] = 0.0 if rng.random() < 0.5 else d[a] * 1e-9  # along the face, exactly or nearly
        d /= np.linalg.norm(d)
        o = touch - d * 10.0 ** rng.uniform(0, 5)
        out.append((o.astype(np.float32), d.astype(np.float32), c.astype(np.float32), np.float32(r)))
    return out


def walk(b, o, d):
    stack_row = np.empty(layout.STACK, np.int32)
    stack_t = np.empty(layout.STACK, np.float32)
    return K.nearest_hit_bvh(
        o[0], o[1], o[2], d[0], d[1], d[2], b.nodes, b.links, b.ordered, b.order, stack_row, stack_t
    )


def test_box_test_keeps_every_grazing_hit(rng):
    hits = misses = 0
    for o, d, c, r in tangent_pairs(rng, 3000):
        spheres = np.array([[c[0]], [c[1]], [c[2]], [r], [1], [1], [1]], np.float32)
        e = c - o  # float32, as the sphere's intersect computes EO
        t, _ = K.prim.intersect_relative(e[0], e[1], e[2], r, d[0], d[1], d[2])
        hit, _ = walk(bvh.build(spheres, threads=1), o, d)
        if t > 0:
            hits += 1
            assert hit == 0, (o, d, c, r, t)
        else:
            misses += 1
            assert hit == -1
    assert hits > 300 and misses > 300, (hits, misses)  # both sides of the edge were tried


def packet_of_rays(rng):
    """An origin and 128 unit directions (packets.PACKET): all one direction (the
    interval test is then exact), a narrow cone (a packet of pixels), or a
    wide one; some rays with a component tiny or zero."""
    o = (rng.uniform(-1, 1, 3) * 10.0 ** rng.uniform(-1, 3)).astype(np.float32)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    spread = rng.choice([0.0, 1e-3, 0.3])
    d = axis + rng.normal(size=(packets.PACKET, 3)) * spread
    if rng.random() < 0.3:
        d[:, int(rng.integers(3))] *= rng.choice([0.0, 1e-9])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d.astype(np.float32)


def test_one_test_for_a_packet_never_drops_a_ray_that_enters(rng):
    """packet_boxes.missed_by_all, the CPU packets' interval test for all their rays at
    once, against each ray's own float32 box test (the row loop of
    packets._packet_box, in NumPy): on boxes placed to be barely entered or barely
    missed by one of the rays, it may only say "missed" where no ray enters."""
    rejected = entered = 0
    for _ in range(400):
        o, d = packet_of_rays(rng)
        inv = np.array([[K.inverse(c) for c in ray] for ray in d], np.float32)
        spread = np.empty(7, np.float32)
        packets._spread(inv[:, 0].copy(), inv[:, 1].copy(), inv[:, 2].copy(), spread)
        for _ in range(10):
            k = int(rng.integers(len(d)))
            t = 10.0 ** rng.uniform(-1, 2)
            point = o + d[k] * np.float32(t)
            # closest hits so far: none, or some, or all about as far as the box
            closest = np.where(rng.random(len(d)) < 0.5, raybench.kernels.trace.FAR, rng.uniform(0, 200, len(d)))
            if rng.random() < 0.5:
                closest = t * rng.uniform(0.5, 1.0, len(d)) * (1 + rng.uniform(-1e-6, 1e-6))
            closest = closest.astype(np.float32)
            spread[6] = closest.max()
            half = 10.0 ** rng.uniform(-4, 1, 3)
            corner = rng.choice([-1.0, 1.0], 3)  # a corner or face of the box near the point
            nudge = rng.uniform(-1e-6, 1e-6, 3) * (np.abs(point) + half)
            centre = point + corner * half * rng.choice([1.0, 1.0, 0.0], 3) + nudge
            lo = (centre - half).astype(np.float32) - o
            hi = (centre + half).astype(np.float32) - o
            t_lo, t_hi = lo * inv, hi * inv  # float32, as the row loop computes them
            near = np.minimum(t_lo, t_hi).max(axis=1)
            far = np.maximum(t_lo, t_hi).min(axis=1)
            any_enters = bool(((near <= far) & (far > 0) & (near <= closest)).any())
            missed = packet_boxes.missed_by_all(*lo, *hi, spread)
            assert not (missed and any_enters), (o, d[k], lo, hi)
            rejected += missed
            entered += any_enters
    assert rejected > 300 and entered > 300, (rejected, entered)  # both outcomes were tried


# --- the builder's tree ----------------------------------------------------------


def check_tree(b: bvh.Bvh, spheres: np.ndarray):
    """Every sphere in exactly one leaf; each child box inside its parent's
    box and around its spheres' padded boxes; depth within MAX_DEPTH."""
    n = spheres.shape[1]
    assert sorted(b.order.tolist()) == list(range(n))
    assert np.array_equal(b.ordered, spheres[:4, b.order])
    seen = np.zeros(n, int)
    pad = sphere.pad(*(spheres[k].astype(np.float64) for k in range(4)))
    deepest = 0
    todo = [(0, None, 1)]
    while todo:
        row, outer, depth = todo.pop()
        deepest = max(deepest, depth)
        for slot in range(2):
            box = b.nodes[row, 6 * slot : 6 * slot + 6].astype(np.float64)
            ref, count = b.links[row, 12 + slot], b.links[row, 14 + slot]
            if count == 0:
                assert (box[:3] > box[3:]).all()  # empty: never hit
                continue
            if outer is not None:
                assert (box[:3] >= outer[:3]).all() and (box[3:] <= outer[3:]).all()
            if count == layout.INNER:
                assert 0 < ref < b.node_count
                todo.append((ref, box, depth + 1))
                continue
            assert 0 < count <= bvh.LEAF_MAX
            for j in range(ref, ref + count):
                i = b.order[j]
                seen[i] += 1
                c, r = spheres[:3, i].astype(np.float64), float(spheres[3, i]) + pad[i] * 0.99
                assert (box[:3] <= c - r).all() and (box[3:] >= c + r).all()
    assert (seen == 1).all()
    assert deepest == b.depth <= layout.MAX_DEPTH
    return deepest


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_tree_structure(rng, kind):
    scene, _ = SCENES[kind](rng, int(rng.integers(1, 3000)))
    check_tree(bvh.build(scene.spheres), scene.spheres)


def binary_subtrees(b: bvh.Bvh):
    """Every child of the binary tree: (its box, its ref and count; an inner
    child's ref replaced by the set of leaves below it)."""
    out, leaves = [], {}

    def below(row):
        if row not in leaves:
            got = set()
            for slot in range(2):
                ref, count = int(b.links[row, 12 + slot]), int(b.links[row, 14 + slot])
                got |= below(ref) if count == layout.INNER else ({(ref, count)} if count else set())
            leaves[row] = frozenset(got)
        return leaves[row]

    for row in range(b.node_count):
        for slot in range(2):
            ref, count = int(b.links[row, 12 + slot]), int(b.links[row, 14 + slot])
            if count:
                key = below(ref) if count == layout.INNER else (ref, count)
                out.append((tuple(b.nodes[row, 6 * slot : 6 * slot + 6].tolist()), key))
    return out


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_collapse_to_4_wide(rng, kind):
    """bvh.collapse: each wide child is a child of the binary tree (the same
    box, over the same leaves), every binary leaf is in the wide tree once,
    the empty slots are count 0 at the point box, and a wide node has 4
    children unless none of them is an inner node that could be opened."""
    scene, _ = SCENES[kind](rng, int(rng.integers(0, 3000)))
    b = bvh.build(scene.spheres)
    wide = bvh.collapse(b)
    links = wide.view(np.int32)
    binary = set(binary_subtrees(b))
    leaves_of = {}

    def walk(row):
        got = set()
        for c in range(layout.WIDTH):
            box = tuple(float(wide[row, lo + c]) for lo in layout.W_LO + layout.W_HI)
            ref, count = int(links[row, layout.W_REF + c]), int(links[row, layout.W_COUNT + c])
            if count == 0:
                assert box == (float(layout.EMPTY),) * 6
                continue
            key = walk(ref) if count == layout.INNER else (ref, count)
            assert (box, key) in binary
            got |= key if count == layout.INNER else {key}
        leaves_of[row] = frozenset(got)
        return leaves_of[row]

    everything = walk(0)
    assert len(leaves_of) == len(wide)  # every row reached, once
    leaves = [key for _, key in binary if isinstance(key, tuple)]
    assert everything == set(leaves) and len(leaves) == len(set(leaves))
    # a node of fewer than 4 children has no inner one left to open
    counts = links[:, layout.W_COUNT : layout.W_COUNT + layout.WIDTH]
    children = (counts != 0).sum(axis=1)
    inner = (counts == layout.INNER).sum(axis=1)
    assert ((children == 4) | (inner == 0)).all() and (children[1:] >= 2).all()
    assert len(wide) <= b.node_count


def test_collapse_of_a_tree_built_in_python_is_the_same(rng):
    """A one-shot picture's tree (built by the builder's Python) is collapsed
    by the same code run as Python: the same rows as compiled."""
    scene, _ = SCENES[str(rng.choice(["generated", "layouts", "cloud", "duplicates"]))](rng, int(rng.integers(1, 400)))
    tree = bvh.build(scene.spheres)
    python = dataclasses.replace(tree, interpreted=True)
    assert bvh.collapse_in_python(python) and not bvh.collapse_in_python(tree)
    # bit for bit (the link columns read as floats hold NaNs: INNER is -1)
    assert np.array_equal(bvh.collapse(python).view(np.int32), bvh.collapse(tree).view(np.int32))
    with bvh.one_shot():  # a compiled tree of at most WIDE spheres, within one_shot: collapsed as Python too
        assert bvh.collapse_in_python(tree)
        assert np.array_equal(bvh.collapse(tree).view(np.int32), bvh.collapse(python).view(np.int32))


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_tree_split_by_all_threads(rng, kind, monkeypatch):
    """Ranges of over bvh.WIDE spheres are split by all threads together, each
    binning and moving a slice; with WIDE and the slices made small, every
    scene takes that path down to small subtrees. The tree is valid, and the
    same on any number of threads."""
    scene, _ = SCENES[kind](rng, int(rng.integers(1, 3000)))
    wide = int(rng.integers(2, 64))
    monkeypatch.setattr(sah_wide, "SLICE", int(rng.integers(1, 300)))
    one = bvh.build(scene.spheres, threads=1, _wide=wide)
    check_tree(one, scene.spheres)
    many = bvh.build(scene.spheres, threads=int(rng.integers(2, 6)), _wide=wide)
    assert np.array_equal(many.links, one.links) and np.array_equal(many.order, one.order)


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_tree_grown_in_runs_given_back(rng, kind, monkeypatch):
    """A large tree's subtrees are grown and packed in runs along the primitives, each run's
    part of the builder's arrays and of the reserved rows given back as it ends (pages.release),
    where those are mapped pages. Mapped from any size (and the reserve from any size too), the
    tree is the one built in NumPy's memory, bit for bit, on any number of threads."""
    scene, _ = SCENES[kind](rng, int(rng.integers(200, 3000)))
    wide = int(rng.integers(2, 64))
    monkeypatch.setattr(sah_wide, "SLICE", int(rng.integers(1, 300)))
    plain = bvh.build(scene.spheres, threads=1, _wide=wide)
    monkeypatch.setattr(pages, "MAPPED_FROM", 0)
    monkeypatch.setattr(pages, "SMALL_PAGES_FROM", 0)
    monkeypatch.setattr(sah_wide, "RUNS", int(rng.integers(2, 9)))
    given_back = bvh.build(scene.spheres, threads=int(rng.integers(1, 6)), _wide=wide)
    check_tree(given_back, scene.spheres)
    assert np.array_equal(given_back.links, plain.links) and np.array_equal(given_back.order, plain.order)


def test_release_gives_back_whole_pages_only():
    """pages.release: an array in NumPy's memory is left as it is; of a mapped one, what lies
    outside the whole pages of the range given back keeps its values."""
    plain = np.arange(100_000, dtype=np.float32)
    pages.release(plain, 10, 90_000)
    assert np.array_equal(plain, np.arange(100_000, dtype=np.float32))
    mapped = pages.scratch(1 << 21, np.float32)
    assert pages.mapped(mapped) and pages.mapped(mapped.view(np.int32)) and not pages.mapped(plain)
    mapped[:] = 1.0
    start, stop = 1000, (1 << 20) + 37  # not on pages' edges: the partial pages at both ends are kept
    pages.release(mapped, start, stop)
    page = pages.mmap.PAGESIZE // 4
    assert (mapped[: -(-start // page) * page] == 1).all() and (mapped[stop // page * page :] == 1).all()


@pytest.mark.parametrize("kind", [*sorted(SCENES), "chain"])
def test_the_uncompiled_builder_gives_the_compiled_tree(rng, kind, monkeypatch):
    """bvh.one_shot(): with the builder not in the cache, its own Python
    builds the tree, which must be the compiled builder's bit for bit (the
    chain takes the splits by count near MAX_DEPTH as well as SAH's)."""
    scene, _ = chain(rng, 0) if kind == "chain" else SCENES[kind](rng, int(rng.integers(1, 1500)))
    compiled_tree = bvh.build(scene.spheres)
    started = []
    monkeypatch.setattr(compiled, "is_ready", lambda name: False)
    monkeypatch.setattr(oneshot, "compile_elsewhere", lambda: started.append(True))
    with bvh.one_shot():
        python_tree = bvh.build(scene.spheres)
    assert python_tree.interpreted and not compiled_tree.interpreted and started == [True]
    assert np.array_equal(python_tree.links, compiled_tree.links)  # every bit of every row, boxes too
    assert np.array_equal(python_tree.ordered.view(np.int32), compiled_tree.ordered.view(np.int32))
    assert np.array_equal(python_tree.order, compiled_tree.order) and python_tree.depth == compiled_tree.depth
    # outside one_shot, and above WIDE within it, the builder is compiled
    assert not bvh.build(scene.spheres).interpreted
    if len(scene) > 2:
        with bvh.one_shot():
            assert not bvh.build(scene.spheres, _wide=2).interpreted


@pytest.mark.parametrize("ready", [False, True])
def test_which_one_shot_builds_run_in_python(ready, monkeypatch):
    """In Python: a scene of at most WIDE spheres whose builder is not cached
    (compiled elsewhere meanwhile), and on a GPU device one of at most
    GPU_PYTHON_MAX whatever the cache holds (no child: its process needs no
    CPU compiler). Outside one_shot(), never."""
    monkeypatch.setattr(compiled, "is_ready", lambda name: ready)
    small, mid, large = bvh.GPU_PYTHON_MAX, bvh.GPU_PYTHON_MAX + 1, bvh.WIDE + 1
    assert oneshot.in_python(small, bvh.WIDE, "cuda") == (False, False)  # not within one_shot
    with bvh.one_shot():
        for device in ("cuda", "wgpu"):
            assert oneshot.in_python(small, bvh.WIDE, device) == (True, False)
            assert oneshot.in_python(mid, bvh.WIDE, device) == (not ready, not ready)
            assert oneshot.in_python(large, bvh.WIDE, device) == (False, False)
        assert oneshot.in_python(small, bvh.WIDE, "cpu") == (not ready, not ready)
        assert oneshot.in_python(large, bvh.WIDE, "cpu") == (False, False)


def test_depth_is_bounded_for_a_chain(rng):
    """SAH would go as deep as the spheres are many; the builder switches to
    splits by count before the stack's depth."""
    scene, _ = chain(rng, 0)
    depth = check_tree(bvh.build(scene.spheres), scene.spheres)
    assert depth > layout.MAX_DEPTH - 10, depth  # the guard was what stopped it


@pytest.mark.parametrize("ties", [False, True])
def test_median_split_halves_by_count(rng, ties):
    """The fallback split by count: a selection in place, so the first half's
    centres are no greater than the second's along the widest axis, and every
    primitive keeps its row (its half size and index move with it)."""
    n = int(rng.integers(2, 300))
    centres = rng.integers(0, 4, (3, n)) if ties else rng.normal(size=(3, n))
    px, py, pz = (np.ascontiguousarray(c, np.float32) for c in centres)
    p = (px, py, pz, rng.random(n).astype(np.float32), np.arange(n, dtype=np.int32))
    before = {tuple(float(a[i]) for a in p) for i in range(n)}
    s = int(rng.integers(0, n - 1))
    e = int(rng.integers(s + 2, n + 1))
    cbox = np.array([*(c[s:e].min() for c in (px, py, pz)), *(c[s:e].max() for c in (px, py, pz))], np.float32)
    outside = [a.copy() for a in p]
    m = sah_steps._median_split(p, s, e, cbox)
    assert m == s + (e - s) // 2
    ext = cbox[3:] - cbox[:3]
    if ext.max() > 0:
        key = (px, py, pz)[int(np.argmax(ext))]  # argmax: the first widest, as the builder picks
        assert key[s:m].max() <= key[m:e].min()
    assert {tuple(float(a[i]) for a in p) for i in range(n)} == before
    for a, old in zip(p, outside):
        assert np.array_equal(a[:s], old[:s]) and np.array_equal(a[e:], old[e:])


def test_parallel_build_is_a_valid_tree(rng):
    """Large scenes split their top on all threads, build their subtrees on
    one thread each, then pack the rows: the same tree as on one thread."""
    scene = raybench.random_spheres(20000, int(rng.integers(2**31)))
    one_thread = bvh.build(scene.spheres, threads=1)
    many = bvh.build(scene.spheres, threads=4)
    check_tree(many, scene.spheres)
    assert np.array_equal(many.links, one_thread.links) and np.array_equal(many.order, one_thread.order)
    assert many.build_s > 0


# --- options and bad input ----------------------------------------------------------


@pytest.mark.parametrize(
    "options,match",
    [
        ({"accel": "bvh", "kernel": "simple"}, "kernel: applies to brute force only"),
        ({"accel": "bvh", "constant_count": True}, "constant_count: applies to brute force only"),
        ({"accel": "kd-tree"}, "accel: must be one of bvh, none"),
    ],
)
def test_bad_accel_options(options, match):
    with pytest.raises(raybench.RaybenchError, match=match):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cpu", **options)


@pytest.mark.gpu
def test_cuda_walk_is_chosen_by_the_tree_size():
    """Packets once the tree outgrows a GPU's L1 (cuda.PACKET_TREE_BYTES), in
    their own default block; a ray at a time below, in its own."""
    if not cuda_backend.available():
        pytest.skip("no CUDA GPU and the simulator is off")
    small_rows = cuda_backend.program.PACKET_TREE_BYTES // layout.NODE_BYTES
    assert cuda_backend.program.choose_walk(small_rows) == "ray"
    assert cuda_backend.program.choose_walk(small_rows + 1) == "packet"
    for n, walk in ((50, "ray"), (30000, "packet")):
        tracer = raybench.backends.tracer("cuda", raybench.random_spheres(n).spheres, 16, 8)
        try:
            assert (tracer.walk, tracer.block) == (walk, cuda_backend.DEFAULT_BLOCK[walk])
            assert (tracer.bvh.node_count * layout.NODE_BYTES > cuda_backend.program.PACKET_TREE_BYTES) == (
                walk == "packet"
            )
        finally:
            tracer.close()


@pytest.mark.parametrize(
    "options,match",
    [
        ({"walk": "sideways"}, "walk: must be one of ray, packet, got 'sideways'"),
        ({"walk": "ray", "accel": "none"}, "walk: applies to the BVH walk only"),
    ],
)
@pytest.mark.gpu
def test_bad_walk_options(options, match):
    if not cuda_backend.available():
        pytest.skip("no CUDA GPU and the simulator is off")
    with pytest.raises(raybench.RaybenchError, match=match):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cuda", **options)


@pytest.mark.gpu
def test_cuda_brute_force_options_refused_with_bvh():
    if not cuda_backend.available():
        pytest.skip("no CUDA GPU and the simulator is off")
    with pytest.raises(raybench.RaybenchError, match="rays: applies to brute force only"):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cuda", accel="bvh", rays=2)


def test_default_is_bvh_and_reports_build_time():
    frame = raybench.render(raybench.random_spheres(50), width=16, height=8, device="cpu")
    assert frame.build_s is not None and frame.build_s >= 0
    assert raybench.render(raybench.random_spheres(50), width=16, height=8, device="cpu", accel="none").build_s is None


def test_bvh_too_large_for_memory_is_one_line(monkeypatch):
    from raybench.backends.cpu import tracer as cpu

    scene = raybench.random_spheres(10000)
    # room for the frame and the spheres, not for the tree: a pixel is 3
    # colour bytes and a 4-byte hit index, held twice on the host; a sphere 7 float32
    frame = 64 * 48 * 2 * (3 + 4)
    available = frame + 10000 * 7 * 4 + 1000
    monkeypatch.setattr(cpu, "host_available_bytes", lambda threads=0: available)
    need = 10000 * bvh.BUILD_SPHERE_BYTES + frame
    with pytest.raises(raybench.RaybenchError) as info:
        raybench.render(scene, width=64, height=48, device="cpu")
    assert str(info.value) == (
        f"bvh: 10,000 spheres need {need / 2**20:.1f} MiB for the BVH and the frame, "
        f"more than the {available / 2**20:.1f} MiB available on the cpu; use fewer spheres or a smaller size"
    )


@pytest.mark.slow
def test_the_builder_takes_the_triangle_beside_the_sphere():
    """The host builder over a mesh's triangles (its own compiled copy of
    the steps, compiled.rebound): every triangle in one leaf, each leaf's box
    holding its triangles' padded boxes, on one thread and sliced over two;
    and the sphere's trees, built before and after in the same process, the
    same to the bit (the kinds do not share a switch)."""
    import trimesh

    from raybench.kernels.primitives import triangle
    from raybench.meshes import Mesh, mesh_leaves

    scene = raybench.random_spheres(3000, seed=4)
    before = bvh.build(scene.spheres, threads=2)
    shape = trimesh.creation.icosphere(subdivisions=3)
    leaves = mesh_leaves(Mesh(np.float32(shape.vertices), np.int32(shape.faces)))
    plain = triangle.make(lambda f: f)
    for wide in (bvh.WIDE, 256):
        tree = bvh.build(leaves, threads=2, primitive=triangle, _wide=wide)
        assert sorted(tree.order.tolist()) == list(range(leaves.shape[1]))
        assert (tree.ordered == leaves[:9, tree.order]).all()
        stack, seen = [0], 0
        while stack:
            row = stack.pop()
            for c in range(2):
                ref, count = tree.links[row, layout.REF + c], tree.links[row, layout.COUNT + c]
                lo = tree.nodes[row, layout.CHILD_BOX[c] : layout.CHILD_BOX[c] + 3]
                hi = tree.nodes[row, layout.CHILD_BOX[c] + 3 : layout.CHILD_BOX[c] + 6]
                if count == layout.INNER:
                    stack.append(ref)
                    continue
                for j in range(ref, ref + count):
                    box = np.float32(plain.bounds(tree.ordered, j))
                    assert (lo <= box[:3]).all() and (box[3:] <= hi).all()
                seen += count
        assert seen == leaves.shape[1]
    after = bvh.build(scene.spheres, threads=2)
    assert (before.nodes.view(np.int32) == after.nodes.view(np.int32)).all() and (before.order == after.order).all()


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["sphere", "triangle", "mixed"])
def test_the_cpus_tree_is_held_and_cut_as_its_kind_says(kind):
    """The host tree for the cpu holds its leaf buffer in the memory order
    of the kind's CPU_LEAF_ORDER (a triangle's nine values side by side),
    the GPUs' in rows, each its primitives' leaf rows in its order, and
    otherwise the same tree to the bit; cut with the kind's
    PACKETS_NODE_COST (the cpu's packets' tree), the triangle's has fewer,
    larger leaves, the others' are the same tree. On one thread and sliced
    over two."""
    from raybench.kernels.primitives import KINDS

    primitive = KINDS[kind]
    buffer = {
        "sphere": lambda: raybench.random_spheres(3000, seed=4).spheres,
        "triangle": lambda: _icosphere_leaves(4),
        "mixed": _mixed_leaves,
    }[kind]()
    for wide in (bvh.WIDE, 256):
        cpu = bvh.build(buffer, threads=2, primitive=primitive, _wide=wide)
        gpu = bvh.build(buffer, threads=2, device="cuda", primitive=primitive, _wide=wide)
        packets = bvh.build(buffer, threads=2, primitive=primitive, _wide=wide, node_cost=primitive.PACKETS_NODE_COST)
        assert gpu.ordered.flags.c_contiguous
        for held in (cpu.ordered.flags, packets.ordered.flags):
            assert held.f_contiguous if primitive.CPU_LEAF_ORDER == "F" else held.c_contiguous
        for tree in (cpu, gpu, packets):
            expected = buffer[: primitive.LEAF_ROWS, tree.order].copy()
            if kind == "mixed":  # a triangle's nine rows, a sphere's four and zeros, then the tag
                expected = buffer[: layout.TRI_ROWS + 1, tree.order].copy()
                expected[layout.TRI_ROWS] = buffer[-1, tree.order]
                expected[sphere.LEAF_ROWS : layout.TRI_ROWS, expected[layout.TRI_ROWS] == layout.MIX_SPHERE] = 0.0
            assert (tree.ordered == expected).all()
        assert (cpu.nodes.view(np.int32) == gpu.nodes.view(np.int32)).all() and (cpu.order == gpu.order).all()
        leaves = [_leaf_counts(tree) for tree in (packets, cpu)]
        assert all(max(c) <= bvh.LEAF_MAX and sum(c) == buffer.shape[1] for c in leaves)
        if primitive.PACKETS_NODE_COST == bvh.NODE_COST:
            assert (packets.nodes.view(np.int32) == cpu.nodes.view(np.int32)).all()
        else:  # the triangle's: fewer leaves, more triangles each
            assert len(leaves[0]) < len(leaves[1]) and np.mean(leaves[0]) > np.mean(leaves[1])
    assert KINDS["triangle"].CPU_LEAF_ORDER == "F"  # what the measured frames were (docs/triangles.md)
    assert KINDS["triangle"].PACKETS_NODE_COST > bvh.NODE_COST


def _leaf_counts(tree) -> list[int]:
    """The primitive count of every leaf of a binary tree, from the root."""
    counts, stack = [], [0]
    while stack:
        row = stack.pop()
        for c in range(2):
            ref, count = tree.links[row, layout.REF + c], tree.links[row, layout.COUNT + c]
            if count == layout.INNER:
                stack.append(ref)
            elif count > 0:
                counts.append(int(count))
    return counts


# --- trees over primitives whose boxes are not cubes: refitted to their leaves' boxes ----


def _icosphere_leaves(subdivisions):
    import trimesh

    from raybench.meshes import Mesh, mesh_leaves

    shape = trimesh.creation.icosphere(subdivisions=subdivisions)
    return mesh_leaves(Mesh(np.float32(shape.vertices), np.int32(shape.faces)))


def _mixed_leaves():
    from raybench.scene_meshes import mixed_leaves

    spheres = raybench.random_spheres(600, seed=5).spheres
    return mixed_leaves(spheres, _icosphere_leaves(3))


def _child_boxes(tree, plain):
    """Each reachable child of the tree: (row, its box, the union of what it
    holds: its inner node's two boxes, or its leaves' padded boxes)."""
    out, stack = [], [0]
    while stack:
        row = stack.pop()
        for c in range(2):
            ref, count = tree.links[row, layout.REF + c], tree.links[row, layout.COUNT + c]
            if count == 0:
                continue
            box = tree.nodes[row, layout.CHILD_BOX[c] : layout.CHILD_BOX[c] + 6]
            if count == layout.INNER:
                assert ref > row  # what the refit relies on: a row's inner children come after it
                stack.append(ref)
                held = np.stack([tree.nodes[ref, k : k + 6] for k in layout.CHILD_BOX])
            else:
                held = np.float32([plain.bounds(tree.ordered, j) for j in range(ref, ref + count)])
            out.append((row, box, np.concatenate([held[:, :3].min(axis=0), held[:, 3:].max(axis=0)])))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["triangle", "mixed"])
def test_a_tree_over_triangles_is_refit_to_its_leaves_boxes(kind, monkeypatch):
    """The host builder bins one half size a primitive, the cube around its
    box; for the triangle (and the mixed kind's triangles) the tree's boxes
    are then refitted: every child box is exactly the union of the boxes it
    holds (so it holds every leaf's padded box, and no more), inside the
    box built over the cubes, and for a mesh alone a lower SAH cost (the
    mixed kind's root shrinks too, which the cost divides by); on one thread
    and sliced over two (the wide top's rows too)."""
    from raybench.bvh import cost, sah
    from raybench.kernels.primitives import KINDS

    primitive = KINDS[kind]
    leaves = _icosphere_leaves(3) if kind == "triangle" else _mixed_leaves()
    plain = primitive.make(lambda f: f)
    for wide in (bvh.WIDE, 256):
        tree = bvh.build(leaves, threads=2, primitive=primitive, _wide=wide)
        with monkeypatch.context() as m:
            m.setattr(sah, "_tighten", lambda *a: None)
            cubes = bvh.build(leaves, threads=2, primitive=primitive, _wide=wide)
        assert (tree.links[:, layout.REF :] == cubes.links[:, layout.REF :]).all()  # the same tree, other boxes
        assert (tree.order == cubes.order).all()
        for row, box, held in _child_boxes(tree, plain):
            assert (box == held).all(), (row, box, held)
        for c in layout.CHILD_BOX:
            assert (cubes.nodes[:, c : c + 3] <= tree.nodes[:, c : c + 3]).all()
            assert (tree.nodes[:, c + 3 : c + 6] <= cubes.nodes[:, c + 3 : c + 6]).all()
        if kind == "triangle":
            assert cost.sah_cost(tree.nodes) < 0.97 * cost.sah_cost(cubes.nodes)


@pytest.mark.slow
def test_the_sphere_tree_is_not_refit_and_would_not_change(monkeypatch):
    """A sphere's box is the cube the builder bins, so its tree is left as
    built: the refit is never called for it, and run on its tree anyway it
    changes no bit (the tree's hash the same), on one thread and sliced."""
    import hashlib

    spheres = raybench.random_spheres(5000, seed=6).spheres
    for wide in (bvh.WIDE, 256):
        tree = bvh.build(spheres, threads=2, _wide=wide)
        digest = hashlib.sha256(tree.nodes.tobytes()).hexdigest()
        refit = tree.nodes.copy()
        sah_steps._refit(refit, refit.view(np.int32), tree.ordered)
        assert hashlib.sha256(refit.tobytes()).hexdigest() == digest

        def never(*args):
            raise AssertionError("the sphere's tree was refitted")

        with monkeypatch.context() as m:
            m.setattr(sah_steps, "_refit", never)
            again = bvh.build(spheres, threads=2, _wide=wide)
        assert hashlib.sha256(again.nodes.tobytes()).hexdigest() == digest


@pytest.mark.slow
@pytest.mark.parametrize("tree_width", [2, 4])
def test_a_refit_trees_frame_is_brute_forces(tree_width):
    """An icosphere of more triangles than WIDE (the top split by every
    thread) seen from (0, 0, -3): the refitted tree's walk, the binary tree
    a ray at a time and the 4-wide packets, hits every pixel brute force hits."""
    leaves = _icosphere_leaves(4)
    camera = raybench.Camera(position=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)
    basis = camera.basis(160, 100)
    frames = []
    for options in ({"tree_width": tree_width}, {"accel": "none", "kernel": "simple"}):
        with raybench.backends.tracer("cpu", leaves, 160, 100, primitive="triangle", threads=2, **options) as tracer:
            tracer.trace(basis)
            frames.append((tracer.hits.copy(), tracer.image.copy()))
    (hits, image), (brute_hits, brute_image) = frames
    assert 0.1 < (hits >= 0).mean() < 0.5
    assert (hits == brute_hits).all() and (image == brute_image).all()


@pytest.mark.slow
def test_the_cpu_cuts_a_meshs_tree_for_the_walk_that_reads_it():
    """The cpu's tracer of a mesh under the thesis's shading (its packets of
    primary rays alone) walks a tree cut with the triangle's
    PACKETS_NODE_COST: fewer 4-wide rows than the tree that Whitted's
    tracer walks (cut with NODE_COST, every ray of its own too), over the
    same triangles, and the same picture of what both see first."""
    from raybench.bench import meshes
    from raybench.mesh_render import mesh_scene

    scene = mesh_scene(meshes.icosphere(20 * 4**4))
    with (
        raybench.Renderer(scene, 96, 60, device="cpu", threads=2) as thesis,
        raybench.Renderer(scene, 96, 60, device="cpu", threads=2, shading="whitted") as whitted,
    ):
        first, second = thesis.render(), whitted.render()
        assert thesis.tracer.wide.shape[0] < whitted.tracer.wide.shape[0]
        assert sorted(thesis.tracer.bvh.order.tolist()) == sorted(whitted.tracer.bvh.order.tolist())
    assert (first.hits == second.hits).all()
