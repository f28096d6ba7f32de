// Steps 1 and 2 of the build (cuda_build._bounds_parts, _bounds_merge,
// _morton): the box of the spheres' centres, then each one's 30-bit Morton
// code in it, beside its index.

// The primitives' buffer, `items` at binding 1, and extent: the
// primitive's piece (sphere_build.wgsl).
// [0, 6): the centres' box (lo x, y, z, hi x, y, z); [6, 9): each axis's
// cells per unit; from PARTS_AT, 6 floats a workgroup of bounds_parts.
@group(0) @binding(2) var<storage, read_write> bounds: array<f32>;
@group(0) @binding(3) var<storage, read_write> keys: array<u32>;
@group(0) @binding(4) var<storage, read_write> values: array<u32>;

var<workgroup> box_lo: array<vec3<f32>, THREADS>;
var<workgroup> box_hi: array<vec3<f32>, THREADS>;

// The workgroup's boxes united into box_lo[0], box_hi[0] (a tree of
// minima and maxima; THREADS a power of 2).
fn reduce_box(t: u32) {
    for (var step = THREADS / 2u; step > 0u; step = step / 2u) {
        workgroupBarrier();
        if (t < step) {
            box_lo[t] = min(box_lo[t], box_lo[t + step]);
            box_hi[t] = max(box_hi[t], box_hi[t + step]);
        }
    }
    workgroupBarrier();
}

// The box of the centres workgroup b strides over (every parts * THREADS-th).
@compute @workgroup_size(THREADS)
fn bounds_parts(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    var lo = vec3<f32>(BIG);
    var hi = vec3<f32>(-BIG);
    for (var i = wg.x * THREADS + t; i < params.n; i = i + params.parts * THREADS) {
        let c = extent(i).centre;
        lo = min(lo, c);
        hi = max(hi, c);
    }
    box_lo[t] = lo;
    box_hi[t] = hi;
    reduce_box(t);
    if (t == 0u) {
        let at = PARTS_AT + 6u * wg.x;
        bounds[at] = box_lo[0].x;
        bounds[at + 1u] = box_lo[0].y;
        bounds[at + 2u] = box_lo[0].z;
        bounds[at + 3u] = box_hi[0].x;
        bounds[at + 4u] = box_hi[0].y;
        bounds[at + 5u] = box_hi[0].z;
    }
}

// AXIS_CELLS / d correctly rounded, for d > 0 (normal): WGSL's division may
// be 2.5 ulp off, and the codes must be the model's (and CUDA's, whose
// division rounds correctly). d = m 2^(e - 23), m of 24 bits; AXIS_CELLS =
// 2^CELL_BITS, so the quotient is 2^47 / m (long division in integers,
// rounded to nearest, ties to even) times 2^(CELL_BITS - 24 - e). A quotient
// past float32's range (d under 1e-35) is its largest float.
fn cells_per_unit(d: f32) -> f32 {
    let bits = bitcast<u32>(d);
    let e = i32((bits >> 23u) & 0xffu) - 127;
    let m = (bits & 0x7fffffu) | 0x800000u;
    var q = 0u;
    var r = 1u;  // the numerator's one bit, 2^47, then 47 zeros shifted in
    for (var i = 0u; i < 47u; i = i + 1u) {
        r = r * 2u;
        q = q * 2u;
        if (r >= m) {
            r = r - m;
            q = q + 1u;
        }
    }
    if (2u * r > m || (2u * r == m && (q & 1u) == 1u)) {
        q = q + 1u;
    }
    let k = i32(CELL_BITS) - 24 - e;
    if (k > 103) {  // 2^24 2^k past float32's range
        return BIG;
    }
    return ldexp(f32(q), k);
}

// The parts united (one workgroup), and the cells per unit of each axis.
@compute @workgroup_size(THREADS)
fn bounds_merge(@builtin(local_invocation_index) t: u32) {
    var lo = vec3<f32>(BIG);
    var hi = vec3<f32>(-BIG);
    for (var k = t; k < params.parts; k = k + THREADS) {
        let at = PARTS_AT + 6u * k;
        lo = min(lo, vec3<f32>(bounds[at], bounds[at + 1u], bounds[at + 2u]));
        hi = max(hi, vec3<f32>(bounds[at + 3u], bounds[at + 4u], bounds[at + 5u]));
    }
    box_lo[t] = lo;
    box_hi[t] = hi;
    reduce_box(t);
    if (t < 3u) {
        let l = box_lo[0][t];
        let h = box_hi[0][t];
        bounds[t] = l;
        bounds[3u + t] = h;
        bounds[6u + t] = select(0.0, cells_per_unit(h - l), h > l);
    }
}

// The cell (0 .. AXIS_CELLS - 1) of coordinate c on axis a (cuda_build._cell).
fn cell(c: f32, a: u32) -> u32 {
    let lo = bounds[a];
    if (bounds[3u + a] > lo) {
        return min(u32((c - lo) * bounds[6u + a]), AXIS_CELLS - 1u);
    }
    return 0u;
}

// The 10 bits of v spread to every third bit (bit k to bit 3k).
fn spread(x: u32) -> u32 {
    var v = (x * 0x00010001u) & 0xFF0000FFu;
    v = (v * 0x00000101u) & 0x0F00F00Fu;
    v = (v * 0x00000011u) & 0xC30C30C3u;
    return (v * 0x00000005u) & 0x49249249u;
}

@compute @workgroup_size(THREADS)
fn morton(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
          @builtin(local_invocation_index) t: u32) {
    let i = element(wg, groups, t);
    if (i >= params.n) {
        return;
    }
    let c = extent(i).centre;
    let x = cell(c.x, 0u);
    let y = cell(c.y, 1u);
    let z = cell(c.z, 2u);
    keys[i] = (spread(x) << 2u) | (spread(y) << 1u) | spread(z);
    values[i] = i;
}
