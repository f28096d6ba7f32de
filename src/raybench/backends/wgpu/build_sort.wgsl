// Step 3 of the build (cuda_build._count, _scan, _scatter): the (code,
// index) pairs sorted by code, an LSD radix sort of DIGIT_BITS a pass, each
// pass three dispatches. A workgroup sorts a tile of TILE keys, each
// invocation ITEMS consecutive ones. The scatter is stable, so equal codes
// keep their indices' order, the tie-break Karras's hierarchy needs.
//
// Where cuda's scatter ranks a key among its digit's by counters per digit
// and thread (32 KiB of shared memory, over WebGPU's 16 KiB default), this
// one first sorts the tile by the digit in workgroup memory, SPLIT_BITS at
// a time (a stable split into 2^SPLIT_BITS buckets by one scan of each
// invocation's counts of each, packed two to a word: a workgroup scan is 8
// steps of two barriers, the floor of this sort), so that a key's rank is
// its place past its digit's first in the tile.
//
// And where cuda's scan is one block's over every digit's counts in a row,
// this one is a workgroup a digit, each over its own tiles' counts (then
// every digit's total, from which each scatter finds where its digits
// start): one workgroup of WebGPU's 256 would walk n / 4096 counts each.

@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> values_in: array<u32>;
// hist[d * tiles + b]: tile b's keys of digit d, then (after scan) how many
// keys of digit d the tiles before b hold; hist[RADIX * tiles + d]: digit
// d's keys in all.
@group(0) @binding(3) var<storage, read_write> hist: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> values_out: array<u32>;

var<workgroup> counts: array<atomic<u32>, RADIX>;
var<workgroup> sums: array<vec4<u32>, THREADS>;
var<workgroup> tile_k: array<u32, TILE>;
var<workgroup> tile_v: array<u32, TILE>;
var<workgroup> start: array<u32, RADIX>;
var<workgroup> first: array<u32, RADIX>;
var<workgroup> bucket_first: array<u32, BUCKETS>;

fn digit(key: u32) -> u32 {
    return (key >> params.shift) & (RADIX - 1u);
}

// The tile of a workgroup (workgroups laid out in 2-D past 65535).
fn tile_of(wg: vec3<u32>, groups: vec3<u32>) -> u32 {
    return wg.y * groups.x + wg.x;
}

// v's exclusive prefix sums over the workgroup's invocations, and their
// totals: Hillis and Steele's scan in sums, four sums at once (each word
// may hold two 16-bit counts: no sum exceeds TILE). Every invocation calls it.
fn workgroup_scan(t: u32, v: vec4<u32>) -> array<vec4<u32>, 2> {
    sums[t] = v;
    for (var step = 1u; step < THREADS; step = step * 2u) {
        workgroupBarrier();
        var add = vec4<u32>(0u);
        if (t >= step) {
            add = sums[t - step];
        }
        workgroupBarrier();
        sums[t] = sums[t] + add;
    }
    workgroupBarrier();
    let inclusive = sums[t];
    let total = sums[THREADS - 1u];
    workgroupBarrier();  // all have read before sums is written again
    return array<vec4<u32>, 2>(inclusive - v, total);
}

// Bucket q's word of a vec4 of 8 counts packed two to a word (16 bits
// each), as a one-hot mask: selects, not a private array indexed by data
// (which a GPU keeps in local memory).
fn word_of(q: u32) -> vec4<u32> {
    return select(vec4<u32>(0u), vec4<u32>(0xffffffffu), vec4<u32>(0u, 1u, 2u, 3u) == vec4<u32>(q / 2u));
}

// Count q of 8 packed in c.
fn packed(c: vec4<u32>, q: u32) -> u32 {
    let w = c & word_of(q);
    return ((w.x | w.y | w.z | w.w) >> (16u * (q % 2u))) & 0xffffu;
}

@compute @workgroup_size(THREADS)
fn count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
         @builtin(local_invocation_index) t: u32) {
    let b = tile_of(wg, groups);
    if (b >= params.tiles) {
        return;
    }
    for (var d = t; d < RADIX; d = d + THREADS) {
        atomicStore(&counts[d], 0u);
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k = k + 1u) {
        let i = b * TILE + k * THREADS + t;
        if (i < params.n) {
            atomicAdd(&counts[digit(keys_in[i])], 1u);
        }
    }
    workgroupBarrier();
    for (var d = t; d < RADIX; d = d + THREADS) {
        hist[d * params.tiles + b] = atomicLoad(&counts[d]);
    }
}

// Digit d's counts (workgroup d) to their exclusive prefix sums over the
// tiles, SCAN_CHUNK at a time (each invocation SCAN_ITEMS consecutive
// ones), and their total.
@compute @workgroup_size(THREADS)
fn scan(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let tiles = params.tiles;
    let row = wg.x * tiles;
    var carry = 0u;
    for (var base = 0u; base < tiles; base = base + SCAN_CHUNK) {
        var v: array<u32, SCAN_ITEMS>;
        var s = 0u;
        for (var k = 0u; k < SCAN_ITEMS; k = k + 1u) {
            let j = base + t * SCAN_ITEMS + k;
            v[k] = select(0u, hist[row + j], j < tiles);
            s = s + v[k];
        }
        let scanned = workgroup_scan(t, vec4<u32>(s, 0u, 0u, 0u));
        var run = carry + scanned[0].x;
        for (var k = 0u; k < SCAN_ITEMS; k = k + 1u) {
            let j = base + t * SCAN_ITEMS + k;
            if (j < tiles) {
                hist[row + j] = run;
            }
            run = run + v[k];
        }
        carry = carry + scanned[1].x;
    }
    if (t == 0u) {
        hist[RADIX * tiles + wg.x] = carry;
    }
}

@compute @workgroup_size(THREADS)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
           @builtin(local_invocation_index) t: u32) {
    let b = tile_of(wg, groups);
    if (b >= params.tiles) {
        return;
    }
    let base = b * TILE;
    let valid = min(TILE, params.n - base);
    // where each digit's keys start: the digits' totals scanned
    let total = select(0u, hist[RADIX * params.tiles + t], t < RADIX);
    let before = workgroup_scan(t, vec4<u32>(total, 0u, 0u, 0u))[0].x;
    if (t < RADIX) {
        first[t] = before;
    }
    // coalesced loads; past the end, keys of every digit bit set, which stay last
    for (var k = 0u; k < ITEMS; k = k + 1u) {
        let j = k * THREADS + t;
        if (j < valid) {
            tile_k[j] = keys_in[base + j];
            tile_v[j] = values_in[base + j];
        } else {
            tile_k[j] = 0xffffffffu;
            tile_v[j] = 0u;
        }
    }
    workgroupBarrier();
    // the tile sorted by the digit, stably, SPLIT_BITS at a time
    for (var low = 0u; low < DIGIT_BITS; low = low + SPLIT_BITS) {
        let at = params.shift + low;
        var mine_k: array<u32, ITEMS>;
        var mine_v: array<u32, ITEMS>;
        var mine = vec4<u32>(0u);  // this invocation's keys of each bucket, packed
        for (var k = 0u; k < ITEMS; k = k + 1u) {
            mine_k[k] = tile_k[t * ITEMS + k];
            mine_v[k] = tile_v[t * ITEMS + k];
            let q = (mine_k[k] >> at) & (BUCKETS - 1u);
            mine = mine + (word_of(q) & vec4<u32>(1u << (16u * (q % 2u))));
        }
        // its barriers: every key read before any is moved
        let scanned = workgroup_scan(t, mine);
        // where each bucket's keys start in the tile: the keys of the buckets before it
        if (t < BUCKETS) {
            var run = 0u;
            for (var q = 0u; q < t; q = q + 1u) {
                run = run + packed(scanned[1], q);
            }
            bucket_first[t] = run;
        }
        workgroupBarrier();
        // a key's place: its bucket's first, then the keys of its bucket
        // held by the invocations before this one, then by this one before it
        for (var k = 0u; k < ITEMS; k = k + 1u) {
            let q = (mine_k[k] >> at) & (BUCKETS - 1u);
            var to = bucket_first[q] + packed(scanned[0], q);
            for (var e = 0u; e < k; e = e + 1u) {
                to = to + select(0u, 1u, ((mine_k[e] >> at) & (BUCKETS - 1u)) == q);
            }
            tile_k[to] = mine_k[k];
            tile_v[to] = mine_v[k];
        }
        workgroupBarrier();
    }
    // where each digit starts in the tile
    for (var k = 0u; k < ITEMS; k = k + 1u) {
        let j = t * ITEMS + k;
        let d = digit(tile_k[j]);
        if (j == 0u || digit(tile_k[j - 1u]) != d) {
            start[d] = j;
        }
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k = k + 1u) {
        let j = k * THREADS + t;
        if (j < valid) {
            let d = digit(tile_k[j]);
            let to = first[d] + hist[d * params.tiles + b] + j - start[d];
            keys_out[to] = tile_k[j];
            values_out[to] = tile_v[j];
        }
    }
}
