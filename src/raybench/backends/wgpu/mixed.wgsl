// kernels/primitives/mixed.py's WGSL twin: spheres and triangles in one
// tree, each primitive either by its tag, every answer the sphere's or the
// triangle's own. shader.py puts it in sphere.wgsl's place after
// triangle_box.wgsl, sphere.wgsl and triangle.wgsl, whose declarations it
// renames sphere_... and triangle_... (namespace.py): nothing here tests a
// ray against a sphere or a triangle. What it declares itself is what WGSL
// cannot take from the Python: the two buffers' layout (WGSL takes no
// buffer as an argument, so each kind's readers are written for them), and
// the walks' names, each dispatching on the tag as mixed.py's by_tag does.

// A primitive of the scene's buffer (compute.py's mixed rows): a triangle's
// struct Facet's members (its vertices, its colour, its corners' normals,
// zeros where it has none; the host puts triangle.wgsl's in, as
// shader.py's MIXED_CONSTANTS say) and the tag. A sphere's centre and radius are
// its first four values and its colour is in the colour's fields, zeros
// elsewhere: the host moves it there from the Python buffer's rows RED,
// GREEN and BLUE, so that the shading (trace.wgsl, whitted.wgsl,
// wavefront.wgsl) reads spheres[i].red, green and blue of either kind, where
// mixed.py's colour asks the tag.
struct Tagged {
    FACET_MEMBERS
    tag: f32,
}
alias Sphere = Tagged;

// The tree's leaf buffer (bvh.ordered transposed): primitive k's
// MIX_LEAF values from MIX_LEAF * k, a triangle's nine vertex values (a
// sphere's centre and radius, then zeros) and the tag.
@group(0) @binding(5) var<storage, read> ordered: array<f32>;

const MIX_SPHERE: f32 = MIXED_SPHERE_TAG;
const MIX_LEAF: i32 = MIXED_LEAF_WORDS;

// tag_of: primitive k's tag in the scene's buffer.
fn tag_of(k: i32) -> f32 {
    return spheres[k].tag;
}

// leaf_tag: primitive k's tag in the tree's leaf buffer.
fn leaf_tag(k: i32) -> f32 {
    return ordered[MIX_LEAF * k + MIX_LEAF - 1];
}

// The sphere's readers on these buffers (sphere.wgsl's read_sphere and
// read_leaf, for its rows): (cx, cy, cz, r).
fn sphere_read_sphere(k: i32) -> vec4<f32> {
    return vec4<f32>(spheres[k].v[0], spheres[k].v[1], spheres[k].v[2], spheres[k].v[3]);
}

fn sphere_read_leaf(k: i32) -> vec4<f32> {
    let i = MIX_LEAF * k;
    return vec4<f32>(ordered[i], ordered[i + 1], ordered[i + 2], ordered[i + 3]);
}

// The triangle's reader of the leaf buffer (triangle.wgsl's read_leaf, for
// nine values a triangle); its read_triangle reads the scene's rows as they are.
fn triangle_read_leaf(k: i32) -> triangle_Triangle {
    let i = MIX_LEAF * k;
    return triangle_corners(array<f32, 9>(ordered[i], ordered[i + 1], ordered[i + 2], ordered[i + 3],
        ordered[i + 4], ordered[i + 5], ordered[i + 6], ordered[i + 7], ordered[i + 8]));
}

// hit and hit_ahead on the scene's buffer, leaf_hit and leaf_hit_ahead on
// the tree's leaves: each kind's own, by the tag the buffer holds.
fn hit(k: i32, o: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    if (tag_of(k) == MIX_SPHERE) {
        return sphere_hit(k, o, d);
    }
    return triangle_hit(k, o, d);
}

fn hit_ahead(k: i32, o: vec3<f32>, d: vec3<f32>, is_own: bool) -> vec2<f32> {
    if (tag_of(k) == MIX_SPHERE) {
        return sphere_hit_ahead(k, o, d, is_own);
    }
    return triangle_hit_ahead(k, o, d, is_own);
}

fn leaf_hit(k: i32, o: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    if (leaf_tag(k) == MIX_SPHERE) {
        return sphere_leaf_hit(k, o, d);
    }
    return triangle_leaf_hit(k, o, d);
}

fn leaf_hit_ahead(k: i32, o: vec3<f32>, d: vec3<f32>, is_own: bool) -> vec2<f32> {
    if (leaf_tag(k) == MIX_SPHERE) {
        return sphere_leaf_hit_ahead(k, o, d, is_own);
    }
    return triangle_leaf_hit_ahead(k, o, d, is_own);
}

// seen_from's answer for either kind, one type as the walk's leaf_test keeps
// it: the tag and the triangle's Seen, which holds a sphere's (EO, r) as
// mixed.py's does, its four values first (a, then b.x), zeros after.
struct Seen {
    tag: f32,
    rows: triangle_Seen,
}

// from_origin: leaf k as rays from o see it, the kind's own from_origin.
fn from_origin(k: i32, o: vec3<f32>) -> Seen {
    let tag = leaf_tag(k);
    if (tag == MIX_SPHERE) {
        let s = sphere_from_origin(k, o);
        let zero = vec3<f32>(0.0);
        return Seen(tag, triangle_Seen(s.xyz, vec3<f32>(s.w, 0.0, 0.0), zero, zero));
    }
    return Seen(tag, triangle_from_origin(k, o));
}

fn hit_from(seen: Seen, d: vec3<f32>) -> vec2<f32> {
    if (seen.tag == MIX_SPHERE) {
        return sphere_hit_from(vec4<f32>(seen.rows.a, seen.rows.b.x), d);
    }
    return triangle_hit_from(seen.rows, d);
}

fn hit_ahead_from(seen: Seen, d: vec3<f32>, is_own: bool) -> vec2<f32> {
    if (seen.tag == MIX_SPHERE) {
        return sphere_hit_ahead_from(vec4<f32>(seen.rows.a, seen.rows.b.x), d, is_own);
    }
    return triangle_hit_ahead_from(seen.rows, d, is_own);
}

// meets_own: the sphere's rule (a ray leaving a primitive meets it again
// only going into it); the triangle's hit_ahead misses the triangle a ray
// leaves whatever it is told.
fn meets_own(own_inside: bool) -> bool {
    return own_inside;
}

// surface (sphere.wgsl's struct Surface, which the triangle's answers too)
// and rim: the kind's own at primitive i of the scene's buffer.
fn surface(o: vec3<f32>, d: vec3<f32>, t: f32, i: i32) -> Surface {
    if (tag_of(i) == MIX_SPHERE) {
        return sphere_surface(o, d, t, i);
    }
    return triangle_surface(o, d, t, i);
}

fn rim(i: i32) -> f32 {
    if (tag_of(i) == MIX_SPHERE) {
        return sphere_rim(i);
    }
    return triangle_rim(i);
}
