// kernels/shade.py: the thesis's colours, and colour to bytes.

// shade_hit: the sphere's colour darkened towards its rim, colour - (rim - d)
// / rim on every channel; rim: what the primitive's rim() gives.
fn shade_hit(red: f32, green: f32, blue: f32, rim: f32, d: f32) -> vec3<f32> {
    let fade = (rim - d) / rim;
    return vec3<f32>(red - fade, green - fade, blue - fade);
}

// shade_miss: the thesis's background gradient.
fn shade_miss(fx: f32, fy: f32) -> vec3<f32> {
    return vec3<f32>(fx / 1024.0, fy / 1024.0, fx / 786.0);
}

// to_byte: floor(clamp(c, 0, 1) * 255 + 0.5), as a float: the byte it stands for.
fn to_byte(c: f32) -> f32 {
    let k = min(max(c, 0.0), 1.0);
    return floor(k * 255.0 + 0.5);
}
