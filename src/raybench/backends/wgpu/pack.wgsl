// The frame's RGB bytes, packed for the host: the texture holds RGBA (what
// the viewer draws), the host wants (H, W, 3) bytes. Each invocation packs
// four pixels, twelve bytes, into three words of `packed`; pixels past the
// frame's last (the last group of four) repeat it, and the host reads only
// the frame's bytes.

struct Size {
    width: u32,
    height: u32,
}

@group(0) @binding(0) var frame: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> packed: array<u32>;
@group(0) @binding(2) var<uniform> size: Size;

// The byte the trace pass stored: unorm8 holds it exactly, as byte / 255.
fn pixel(p: u32) -> vec3<u32> {
    let texel = textureLoad(frame, vec2<i32>(i32(p % size.width), i32(p / size.width)), 0);
    return vec3<u32>(round(texel.rgb * 255.0));
}

@compute @workgroup_size(64)
fn pack(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let total = size.width * size.height;
    let quad = id.x + id.y * groups.x * 64u;
    if (quad * 4u >= total) {
        return;
    }
    let last = total - 1u;
    let a = pixel(quad * 4u);
    let b = pixel(min(quad * 4u + 1u, last));
    let c = pixel(min(quad * 4u + 2u, last));
    let d = pixel(min(quad * 4u + 3u, last));
    // little-endian words: byte 0 of the frame is the low byte of word 0
    packed[quad * 3u] = a.x | (a.y << 8u) | (a.z << 16u) | (b.x << 24u);
    packed[quad * 3u + 1u] = b.y | (b.z << 8u) | (c.x << 16u) | (c.y << 24u);
    packed[quad * 3u + 2u] = c.z | (d.x << 8u) | (d.y << 16u) | (d.z << 24u);
}
