// kernels/trace.py: the primary ray, and one pixel from ray to stored bytes.

struct Hit {
    index: i32,
    d: f32,
}

// What a search for any ray finds: the sphere (-1: none), its t, its half-chord.
struct Found {
    index: i32,
    t: f32,
    d: f32,
}

// primary_ray: the unit direction of the ray through pixel (x, y)'s centre.
fn primary_ray(x: u32, y: u32) -> vec3<f32> {
    let fx = f32(x);
    let fy = f32(y);
    let u = (fx + 0.5) / f32(frame.width) - 0.5;
    let v = 0.5 - (fy + 0.5) / f32(frame.height);
    let dx = frame.forward.x + frame.right.x * u + frame.up.x * v;
    let dy = frame.forward.y + frame.right.y * u + frame.up.y * v;
    let dz = frame.forward.z + frame.right.z * u + frame.up.z * v;
    let inv = 1.0 / sqrt(dx * dx + dy * dy + dz * dz);
    return vec3<f32>(dx * inv, dy * inv, dz * inv);
}

// store_pixel: shade pixel (x, y) from its nearest hit (-1: none) and store it.
fn store_pixel(x: u32, y: u32, hit: Hit) {
    var c: vec3<f32>;
    if (hit.index >= 0) {
        let s = spheres[hit.index];
        c = shade_hit(s.red, s.green, s.blue, rim(hit.index), hit.d);
    } else {
        c = shade_miss(f32(x), f32(y));
    }
    let bytes = vec3<f32>(to_byte(c.x), to_byte(c.y), to_byte(c.z));
    textureStore(image, vec2<i32>(i32(x), i32(y)), vec4<f32>(bytes / 255.0, 1.0));
    hits[y * frame.width + x] = hit.index;
}

// main: render_pixel, one invocation per pixel; workgroups overhanging the
// image do nothing there.
@compute @workgroup_size(WORKGROUP_X, WORKGROUP_Y)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= frame.width || id.y >= frame.height) {
        return;
    }
    let dir = primary_ray(id.x, id.y);
    let hit = nearest_hit(frame.origin.xyz, dir, frame.count);
    store_pixel(id.x, id.y, hit);
}
