// The buffer dump (`bevy_penumbra_df::buffer_dump`): one thread per view pixel copies what
// Penumbra's passes read into one f32 buffer, plane after plane, row 0 at the top:
//   [0, n)          distance from the camera to the surface along the pixel's ray, metres
//                   (-1: background, turned into NaN on the CPU)
//   [n, 4n)         world-space unit normal, xyz interleaved (0: background or no G-buffer)
//   [4n + l n, …)   mask layer l (the visibility the lighting pass reads, 1 lit)
// and, when the view has distance-field AO (after the L mask layers):
//   [(4 + L) n, …)  AO before contrast and min occlusion (1 open)
//   [(5 + L) n, …)  world-space unit bent normal, xyz interleaved
// and, when the view has the face-normal prepass (after the planes above, A = 4 with
// AO, else 0):
//   [(4 + L + A) n, …)  the face-normal target's winding normal, xyz interleaved
//                       (0: no triangle drawn)
// with n = width × height.
#define_import_path penumbra::lighting::buffer_dump

#import penumbra::df::shadow::gbuffer_normal

struct DumpView {
    view_from_clip: mat4x4<f32>,
    // x, y: size in pixels; z: mask layers; w: 1 when `gbuffer` holds the view's normals.
    size: vec4<u32>,
    // x: 1 when `ambient_occlusion` holds the view's distance-field AO; y: 1 when
    // `face_normals` holds the view's face-normal target.
    ao: vec4<u32>,
}

// Reverse-Z depth (the prepass depth).
@group(0) @binding(0) var depth_texture: texture_2d<f32>;
// Bevy's deferred G-buffer (Rgba32Uint; the octahedral normal in `.a`).
@group(0) @binding(1) var gbuffer: texture_2d<u32>;
@group(0) @binding(2) var masks: texture_2d_array<f32>;
@group(0) @binding(3) var<uniform> view: DumpView;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;
// The AO pass's full-resolution output (AO, bent normal), or one texel.
@group(0) @binding(5) var ambient_occlusion: texture_2d<f32>;
// The face-normal prepass's target (`bevy_penumbra_df::face_normals`), or one texel.
@group(0) @binding(6) var face_normals: texture_2d<f32>;

// View-space position of pixel `xy`'s centre at reverse-Z `depth`.
fn view_position(xy: vec2<u32>, depth: f32) -> vec3<f32> {
    let uv = (vec2<f32>(xy) + 0.5) / vec2<f32>(view.size.xy);
    let ndc = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let v = view.view_from_clip * ndc;
    return v.xyz / v.w;
}

// The surface's world-space normal, or 0 when the view has no G-buffer.
fn surface_normal(xy: vec2<u32>) -> vec3<f32> {
    if view.size.w == 0u {
        return vec3<f32>(0.0);
    }
    return gbuffer_normal(textureLoad(gbuffer, vec2<i32>(xy), 0).a);
}

@compute @workgroup_size(8, 8, 1)
fn dump(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.size.x || gid.y >= view.size.y {
        return;
    }
    let n = view.size.x * view.size.y;
    let i = gid.y * view.size.x + gid.x;
    let depth = textureLoad(depth_texture, vec2<i32>(gid.xy), 0).r;
    var distance = -1.0;
    var normal = vec3<f32>(0.0);
    if depth > 0.0 {
        distance = length(view_position(gid.xy, depth));
        normal = surface_normal(gid.xy);
    }
    out[i] = distance;
    for (var k = 0u; k < 3u; k += 1u) {
        out[n + 3u * i + k] = normal[k];
    }
    for (var l = 0u; l < view.size.z; l += 1u) {
        out[(4u + l) * n + i] = textureLoad(masks, vec2<i32>(gid.xy), i32(l), 0).r;
    }
    var base = (4u + view.size.z) * n;
    if view.ao.x != 0u {
        dump_ao(gid.xy, i, n, base);
        base += 4u * n;
    }
    if view.ao.y != 0u {
        let face = textureLoad(face_normals, vec2<i32>(gid.xy), 0);
        for (var k = 0u; k < 3u; k += 1u) {
            out[base + 3u * i + k] = face[k] * face.w;
        }
    }
}

// The AO plane at `base` and the bent normal's after it.
fn dump_ao(xy: vec2<u32>, i: u32, n: u32, base: u32) {
    let s = textureLoad(ambient_occlusion, vec2<i32>(xy), 0);
    out[base + i] = s.x;
    for (var k = 0u; k < 3u; k += 1u) {
        out[base + n + 3u * i + k] = s[k + 1u];
    }
}
