// What every step of the GPU build shares (build.py prepends the constants,
// taken from their Python definitions, and puts this piece before each
// step's own). The steps port backends/cuda_build.py kernel by kernel.

// One uniform per build, and one per pass of the sort (its shift) and for
// the refit (leaf_max 0): build.py writes them once.
struct Params {
    n: u32,         // the spheres built over (the first n of the binding)
    shift: u32,     // the sort pass's digit
    tiles: u32,     // the sort's tiles: ceil(n / TILE)
    zero: u32,      // 0, which no compiler can know: see exact()
    leaf_max: u32,  // leaves of up to this many spheres (0: a refit, leaves kept)
    sah: u32,       // 1: a leaf where the SAH says ("sah"); 0: every small subtree ("lbvh")
    parts: u32,     // the workgroups of bounds_parts
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;

// No link: the root's link up.
const NONE: u32 = 0xffffffffu;
// A word of the bottom-up pass not yet written (see build_tree.wgsl): a
// NaN's bits, which no box, cost, height or count is.
const UNSET: u32 = 0xffffffffu;

// The invocation's element where a step has one per invocation, its
// workgroups laid out in 2-D past the 65535 a dimension may hold.
fn element(wg: vec3<u32>, groups: vec3<u32>, t: u32) -> u32 {
    return (wg.y * groups.x + wg.x) * THREADS + t;
}

// x, rounded to float32 on its own: WGSL lets a compiler fuse a product
// into a following sum (one rounding less, as CUDA's fma), and an OR with a
// uniform it cannot know keeps it from doing so. The model and the cuda
// simulator round every product; with this, so does the WGSL.
fn exact(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | params.zero);
}
