// kernels/shade.py: the thesis's colours, and colour to bytes.

fn shade_hit(s: Sphere, d: f32) -> vec3<f32> {
    let fade = (s.r - d) / s.r;
    return vec3<f32>(s.red - fade, s.green - fade, s.blue - fade);
}

fn shade_miss(fx: f32, fy: f32) -> vec3<f32> {
    return vec3<f32>(fx / 1024.0, fy / 1024.0, fx / 786.0);
}

// floor(clamp(c, 0, 1) * 255 + 0.5), as a float: the byte it stands for.
fn to_byte(c: f32) -> f32 {
    let k = min(max(c, 0.0), 1.0);
    return floor(k * 255.0 + 0.5);
}
