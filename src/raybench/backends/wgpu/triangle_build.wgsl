// kernels/primitives/triangle.py's answers to the builders, its WGSL twin:
// extent and copy_leaf (here leaf_row: WGSL takes no storage buffer as an
// argument, so the step stores the row). build.py puts this piece, after
// triangle_box.wgsl (pad, box, padded), between build_common.wgsl and each
// step's own, in sphere_build.wgsl's place; nothing else in the build reads a
// triangle's vertices.

// The scene's buffer as the builders bind it: compute.py's triangle rows,
// TRI_SCENE_WORDS float32 a triangle, its vertices A, B, C first (the
// tracer reads the same bytes as triangle.wgsl's struct Sphere).
@group(0) @binding(1) var<storage, read> items: array<f32>;

// A row of the tree's leaf buffer (bvh.ordered): LEAF_ROWS float32, the vertices.
alias Leaf = array<f32, 9>;

// corner: vertex j (0: A, 1: B, 2: C) of triangle k.
fn corner(k: u32, j: u32) -> vec3<f32> {
    let i = TRI_SCENE_WORDS * k + 3u * j;
    return vec3<f32>(items[i], items[i + 1u], items[i + 2u]);
}

// extent: triangle k's padded box, three half sizes (a triangle's box is no cube).
fn extent(k: u32) -> Extent {
    return padded(corner(k, 0u), corner(k, 1u), corner(k, 2u));
}

// leaf_row: what copy_leaf copies, triangle k's vertices (the scene's very
// values), never the colour or the normals.
fn leaf_row(k: u32) -> Leaf {
    let i = TRI_SCENE_WORDS * k;
    return Leaf(items[i], items[i + 1u], items[i + 2u], items[i + 3u], items[i + 4u], items[i + 5u],
                items[i + 6u], items[i + 7u], items[i + 8u]);
}
