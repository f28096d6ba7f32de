// kernels/primitives/sphere.py's answers to the builders, its WGSL twin:
// pad, extent and copy_leaf (here leaf_row: WGSL takes no storage buffer as
// an argument, so the step stores the row). build.py puts this piece between
// build_common.wgsl and each step's own; nothing else in the build reads a
// sphere's centre or radius.

// The scene's buffer as the builders bind it: Scene.spheres' (7, N) float32
// columns padded to 8, two vec4s a sphere (centre and radius, then colour).
@group(0) @binding(1) var<storage, read> items: array<vec4<f32>>;

// A row of the tree's leaf buffer (bvh.ordered): LEAF_ROWS float32.
alias Leaf = vec4<f32>;

// An extent: a padded box as its centre and half its size on each axis.
struct Extent {
    centre: vec3<f32>,
    half_size: vec3<f32>,
}

// pad: the padding of a sphere's box (layout.PAD's rule).
fn pad(cx: f32, cy: f32, cz: f32, r: f32) -> f32 {
    return (r + (abs(cx) + abs(cy) + abs(cz))) * PAD;
}

// read_sphere: the Python's read, sphere k of the scene's buffer, (cx, cy,
// cz, r), which extent and leaf_row read it through, as the Python's do:
// the mixed kind's build gives it a reader of its own rows (mixed_build.wgsl).
fn read_sphere(k: u32) -> vec4<f32> {
    return items[2u * k];
}

// extent: sphere k's padded box, centred on the sphere's centre.
fn extent(k: u32) -> Extent {
    let s = read_sphere(k);
    let pr = s.w + pad(s.x, s.y, s.z, s.w);
    return Extent(s.xyz, vec3<f32>(pr));
}

// leaf_row: what copy_leaf copies, sphere k's row of the leaf buffer (the
// scene's very values).
fn leaf_row(k: u32) -> Leaf {
    return read_sphere(k);
}
