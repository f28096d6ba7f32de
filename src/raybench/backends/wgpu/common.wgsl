// What every ray-tracing kernel binds: the frame's camera and size, the
// spheres, and the two outputs. Layouts match backends/wgpu/compute.py.

// Camera.basis() in rows of four (WGSL pads vec3 to 16 bytes anyway), then
// the frame's size and how many of the loaded spheres to trace.
struct Frame {
    origin: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,   // right * plane_w
    up: vec4<f32>,      // true_up * plane_h
    width: u32,
    height: u32,
    count: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> frame: Frame;
// The scene's spheres, in the layout of sphere.wgsl's struct Sphere, which
// alone reads their geometry.
@group(0) @binding(1) var<storage, read> spheres: array<Sphere>;
// rgba8unorm: the shader stores byte / 255, which the unorm conversion turns
// back into exactly that byte; the viewer draws this texture as it is.
@group(0) @binding(2) var image: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(3) var<storage, read_write> hits: array<i32>;

const FAR: f32 = 3.0e38;  // kernels/trace.py's FAR: farther than any hit
