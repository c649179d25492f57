// Distance-field ambient occlusion: the cone set and the per-object cone march (the
// arithmetic of `penumbra_reference::dfao` and `penumbra_df_core::ao`).
#define_import_path penumbra::df::ao

#import penumbra::df::object::{
    DistanceFieldObject, FLAG_CASTS_OCCLUSION, FLAG_CAST_HIDDEN_SHADOW, FLAG_LIVE, FLAG_TWO_SIDED,
    FLAG_VISIBLE, KIND_VOLUME, ao_transmission, object_kind,
}
#import penumbra::df::distance::object_distance
#import penumbra::df::shadow::{SHELL_VOXELS, cone_interval}

const MAX_CONES: u32 = 16u;
const GOLDEN_ANGLE: f32 = 2.3999633;
const MIN_STEP_FRACTION: f32 = 0.5;

struct AoTraceView {
    view_from_clip: mat4x4<f32>,
    world_from_view: mat3x3<f32>,
    camera_tile: vec3<i32>,
    slot_count: u32,
    camera_offset: vec3<f32>,
    max_distance: f32,
    full_size: vec2<u32>,
    trace_size: vec2<u32>,
    jitter: vec2<u32>,
    divisor: u32,
    cone_count: u32,
    steps_per_cone: u32,
    bias: f32,
    tan_half: f32,
    shaping: f32,
    influence: f32,
    tile_objects_debug: u32,
    // The far field's reach (0: none; `max_distance` is then the switch distance).
    far_distance: f32,
    // Terrains each cone also marches (`heightfields` of the trace).
    heightfield_count: u32,
    // The viewport's origin in the frame buffer: where its pixels are read from the
    // prepass textures (the render target's size; the trace is the viewport's).
    origin: vec2<u32>,
}

// `ao::TILE_OBJECTS_SCALE`.
const TILE_OBJECTS_SCALE: f32 = 1024.0;

// Live, occluding, and visible or a hidden-shadow proxy (`flags::casts_occlusion`).
fn casts_occlusion(o: DistanceFieldObject) -> bool {
    return (o.flags & FLAG_LIVE) != 0u && (o.flags & FLAG_CASTS_OCCLUSION) != 0u
        && (o.flags & (FLAG_VISIBLE | FLAG_CAST_HIDDEN_SHADOW)) != 0u;
}

// Tangent-space centre of cone `k` of `n` (`ao::cone_weight_direction`).
fn cone_direction(k: u32, n: u32) -> vec3<f32> {
    let count = clamp(n, 1u, MAX_CONES);
    let rho = sqrt((f32(k) + 0.5) / f32(count));
    let phi = f32(k) * GOLDEN_ANGLE;
    return vec3<f32>(rho * cos(phi), rho * sin(phi), sqrt(max(1.0 - rho * rho, 0.0)));
}

// Tangent and bitangent of unit `n` (Duff et al. 2017; `ao::tangent_frame`).
fn tangent_frame(n: vec3<f32>) -> mat2x3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return mat2x3<f32>(
        vec3<f32>(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        vec3<f32>(b, s + n.y * n.y * a, -n.y),
    );
}

// How far along the normal and along its cones a receiver's trace through object `obj`
// starts: the view's bias, or AO_FINE_FIELD_BIAS_VOXELS voxels of a finer field
// (`penumbra_df_core::ao::object_bias`).
const AO_FINE_FIELD_BIAS_VOXELS: f32 = 1.5;
fn ao_object_bias(obj: DistanceFieldObject, bias: f32) -> f32 {
    let voxel = obj.conservative_scale;
    if object_kind(obj) == KIND_VOLUME && voxel > 0.0 {
        return min(bias, AO_FINE_FIELD_BIAS_VOXELS * voxel);
    }
    return bias;
}

// The visibility of one cone (from receiver `p` of unit normal `n`, lifted
// `ao_object_bias` along it; unit `axis` rising `rise` per metre) through object `obj` with
// bounding ball `sphere` (w < 0: unbounded). CPU model: `dfao::march_cone`.
fn march_cone(
    obj: DistanceFieldObject,
    sphere: vec4<f32>,
    p: vec3<f32>,
    n: vec3<f32>,
    axis: vec3<f32>,
    rise: f32,
    view: AoTraceView,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> f32 {
    // A receiver inside an analytic shape is not occluded by it: the shape stands in for
    // the receiver's own mesh (a character's capsules).
    if object_kind(obj) != KIND_VOLUME
        && object_distance(obj, p, view.camera_tile, view.camera_offset, atlas, brick_table) < 0.0 {
        return 1.0;
    }
    let bias = ao_object_bias(obj, view.bias);
    let o = p + n * bias;
    var t = bias;
    var t_end = view.max_distance;
    if sphere.w >= 0.0 {
        let interval = cone_interval(o - sphere.xyz, axis, sphere.w, view.tan_half);
        if interval.x > interval.y {
            return 1.0;
        }
        t = max(t, interval.x);
        t_end = min(t_end, interval.y);
    }
    // A two-sided field is read as its surface, not its shell: a receiver on it sits
    // inside its own shell.
    let two_sided = object_kind(obj) == KIND_VOLUME && (obj.flags & FLAG_TWO_SIDED) != 0u;
    let shell = select(0.0, SHELL_VOXELS * obj.conservative_scale, two_sided);
    var v = 1.0;
    for (var i = 0u; i < view.steps_per_cone; i += 1u) {
        if t >= t_end {
            break;
        }
        let d = object_distance(obj, o + axis * t, view.camera_tile, view.camera_offset, atlas, brick_table);
        let cone = max(t * view.tan_half, 1e-6);
        var floor = 0.0;
        if sphere.w >= 0.0 {
            floor = 1.0 - min((sphere.w / cone) * (sphere.w / cone), 1.0);
        }
        let surface = d + shell;
        if surface <= 0.0 {
            v = min(v, floor);
            break;
        }
        let open = max(min(cone, bias + t * rise), 1e-6);
        v = min(v, max(surface / open, floor));
        t += max(d, cone * MIN_STEP_FRACTION);
    }
    v = clamp(v, 0.0, 1.0);
    let shaped = select(0.0, pow(v, view.shaping), v > 0.0);
    let transmission = ao_transmission(obj);
    return transmission + (1.0 - transmission) * shaped;
}

// AO and bent normal (world, around unit `n`) from the cones' visibilities.
// CPU model: `dfao::combine`.
fn combine(visibility: array<f32, MAX_CONES>, count: u32, n: vec3<f32>) -> vec4<f32> {
    let frame = tangent_frame(n);
    var sum = vec3<f32>(0.0);
    var open = vec3<f32>(0.0);
    var ao = 0.0;
    for (var k = 0u; k < count; k += 1u) {
        let w = cone_direction(k, count);
        sum += w * visibility[k];
        open += w;
        ao += visibility[k];
    }
    ao = ao / f32(max(count, 1u));
    let bent = sum - vec3<f32>(open.x, open.y, 0.0) * ao;
    let world = frame[0] * bent.x + frame[1] * bent.y + n * bent.z;
    let len = length(world);
    return vec4<f32>(ao, select(n, world / len, len > 1e-6));
}
