// The GPU re-bake of a posed mesh into its atlas volume (#48): every sample of a
// `resolution³` cube gets the distance to the nearest posed triangle, signed by the
// generalized winding number of all of them (inside where it exceeds ½, so open seams
// and overlapping parts keep a sign), in voxels. Brute force over the triangles, tiled
// through workgroup memory: each invocation owns two samples along x and writes them
// as one `pack2x16float` word of the output, whose rows are padded for
// `copy_buffer_to_texture`. Corners come relative to sample (0, 0, 0).
// Layouts: `penumbra_df_core::rebake`; CPU model: `penumbra_reference::rebake`.
#define_import_path penumbra::df::rebake

struct RebakeParams {
    voxel_size: f32,
    resolution: u32,
    triangles: u32,
    row_words: u32,
}

@group(0) @binding(0) var<uniform> params: RebakeParams;
// Three corners per triangle (`w` unused).
@group(0) @binding(1) var<storage, read> corners: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> samples: array<u32>;

const TRIANGLE_TILE: u32 = 64u;
const FOUR_PI: f32 = 12.566370614359172;

var<workgroup> tile: array<array<vec3<f32>, 3>, TRIANGLE_TILE>;

// The nearest squared distance and the solid angle summed so far at one sample.
struct Accumulator {
    distance_squared: f32,
    solid_angle: f32,
}

fn dot2(v: vec3<f32>) -> f32 {
    return dot(v, v);
}

// The squared distance from `p` to the segment `a + t·e`, `t` in 0..1 (`pa` = p − a).
fn segment_distance_squared(e: vec3<f32>, pa: vec3<f32>) -> f32 {
    let t = clamp(dot(e, pa) / max(dot2(e), 1e-30), 0.0, 1.0);
    return dot2(e * t - pa);
}

// The squared distance from `p` to triangle `abc`: to its plane where `p` projects
// inside it, else to the nearest edge (Quílez's form; a degenerate triangle is its edges).
fn triangle_distance_squared(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    let ba = b - a;
    let cb = c - b;
    let ac = a - c;
    let pa = p - a;
    let pb = p - b;
    let pc = p - c;
    let nor = cross(ba, ac);
    let inside = sign(dot(cross(ba, nor), pa)) + sign(dot(cross(cb, nor), pb))
        + sign(dot(cross(ac, nor), pc));
    if inside < 2.0 {
        return min(
            min(segment_distance_squared(ba, pa), segment_distance_squared(cb, pb)),
            segment_distance_squared(ac, pc),
        );
    }
    let h = dot(nor, pa);
    return h * h / dot2(nor);
}

// The solid angle triangle `abc` subtends at `p` (Van Oosterom and Strackee), signed
// positive when `p` sees its back (inside a counter-clockwise mesh); 0 at a corner.
fn solid_angle(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    let u = a - p;
    let v = b - p;
    let w = c - p;
    let lu = length(u);
    let lv = length(v);
    let lw = length(w);
    let det = dot(u, cross(v, w));
    let div = lu * lv * lw + dot(u, v) * lw + dot(v, w) * lu + dot(w, u) * lv;
    if det == 0.0 && div == 0.0 {
        return 0.0;
    }
    return 2.0 * atan2(det, div);
}

fn accumulate(acc: Accumulator, p: vec3<f32>, t: array<vec3<f32>, 3>) -> Accumulator {
    return Accumulator(
        min(acc.distance_squared, triangle_distance_squared(p, t[0], t[1], t[2])),
        acc.solid_angle + solid_angle(p, t[0], t[1], t[2]),
    );
}

// The signed distance in voxels: negative where the winding number exceeds ½; within
// f16's range (no triangles: as far as it holds).
fn signed_voxels(acc: Accumulator) -> f32 {
    let d = min(sqrt(acc.distance_squared) / params.voxel_size, 65504.0);
    return select(d, -d, acc.solid_angle / FOUR_PI > 0.5);
}

// Loads triangle `first + index` of the buffer into the tile (none past the end).
fn load_tile(first: u32, index: u32) {
    let t = first + index;
    if t < params.triangles {
        tile[index] = array<vec3<f32>, 3>(
            corners[3u * t].xyz,
            corners[3u * t + 1u].xyz,
            corners[3u * t + 2u].xyz,
        );
    }
}

@compute @workgroup_size(4, 4, 4)
fn rebake(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) index: u32,
) {
    let p0 = vec3<f32>(f32(2u * id.x), f32(id.y), f32(id.z)) * params.voxel_size;
    let p1 = p0 + vec3<f32>(params.voxel_size, 0.0, 0.0);
    var a0 = Accumulator(3.0e38, 0.0);
    var a1 = Accumulator(3.0e38, 0.0);
    for (var first = 0u; first < params.triangles; first += TRIANGLE_TILE) {
        workgroupBarrier();
        load_tile(first, index);
        workgroupBarrier();
        let count = min(TRIANGLE_TILE, params.triangles - first);
        for (var k = 0u; k < count; k += 1u) {
            let t = tile[k];
            a0 = accumulate(a0, p0, t);
            a1 = accumulate(a1, p1, t);
        }
    }
    let word = (id.z * params.resolution + id.y) * params.row_words + id.x;
    samples[word] = pack2x16float(vec2<f32>(signed_voxels(a0), signed_voxels(a1)));
}
