// kernels/primitives/mixed.py's answers to the builders, its WGSL twin:
// extent and copy_leaf (here leaf_row), each the sphere's or the triangle's
// own by the primitive's tag. build.py puts it after triangle_box.wgsl,
// sphere_build.wgsl and triangle_build.wgsl, whose declarations it renames
// sphere_... and triangle_... (namespace.py), between build_common.wgsl and
// each step's own; nothing here reads a sphere's or a triangle's geometry
// but the sphere's reader of these rows.

// The scene's buffer as the builders bind it: compute.py's mixed rows,
// MIX_SCENE float32 a primitive (mixed.wgsl's struct Tagged), a triangle's
// vertices first, a sphere's centre and radius first, the tag last. The
// triangle's corner and leaf_row read it as they read a mesh's rows: their
// stride, TRI_SCENE_WORDS, is this buffer's here (build.py).
@group(0) @binding(1) var<storage, read> items: array<f32>;

const MIX_SCENE: u32 = MIXED_SCENE_WORDS;
const MIX_SPHERE: f32 = MIXED_SPHERE_TAG;

// A row of the tree's leaf buffer (bvh.ordered): a triangle's nine vertex
// values (a sphere's four, then zeros) and the tag.
alias Leaf = array<f32, MIXED_LEAF_WORDS>;

// tag_of: primitive k's tag.
fn tag_of(k: u32) -> f32 {
    return items[MIX_SCENE * k + MIX_SCENE - 1u];
}

// The sphere's reader of these rows (sphere_build.wgsl's read_sphere, for
// the sphere's own): (cx, cy, cz, r).
fn sphere_read_sphere(k: u32) -> vec4<f32> {
    let i = MIX_SCENE * k;
    return vec4<f32>(items[i], items[i + 1u], items[i + 2u], items[i + 3u]);
}

// extent: primitive k's padded box, the kind's own (a sphere's cube, a
// triangle's three half sizes).
fn extent(k: u32) -> Extent {
    if (tag_of(k) == MIX_SPHERE) {
        return sphere_extent(k);
    }
    return triangle_extent(k);
}

// leaf_row: what copy_leaf copies, the kind's own row, zeros after a
// sphere's, and the tag.
fn leaf_row(k: u32) -> Leaf {
    let tag = tag_of(k);
    if (tag == MIX_SPHERE) {
        let s = sphere_leaf_row(k);
        return Leaf(s.x, s.y, s.z, s.w, 0.0, 0.0, 0.0, 0.0, 0.0, tag);
    }
    let t = triangle_leaf_row(k);
    return Leaf(t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], tag);
}
