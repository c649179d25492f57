// The global distance field's compose pass: one workgroup per brick job (8³ texels of
// one clipmap level). The workgroup culls the object records 128 at a time into
// workgroup memory — a record is kept when it goes into the field (live, occluding,
// opaque to AO) and its bounding ball grown by the level's reach (band and dilation)
// meets the box of the brick's texel centres — and each invocation takes the smallest
// distance of the kept records at four texels along x, lowers it by the level's
// dilation (grown surfaces: a wall thinner than a texel keeps texels inside it), clamps
// it to ± band, lowers it by one quantum and rounds it to 8 bits (never above the true
// distance), and writes the four as one word. Heightfields (terrain) join like objects:
// each whose box grown by the reach meets the brick's, by its conservative distance.
// Positions are relative to the job's 512 m tile, so a brick composed on any frame gets
// the same values. CPU model: `penumbra_reference::global_sdf::GlobalField::compose_records`;
// the job and buffer layout: `penumbra_df_core::clipmap::{ComposeJob, brick_word}`.
#define_import_path penumbra::df::global_compose

#import penumbra::df::object::{DistanceFieldObject, ao_transmission}
#import penumbra::df::distance::object_distance
#import penumbra::df::shadow::bounding_sphere
#import penumbra::df::ao::casts_occlusion
#import penumbra::df::heightfield::{
    HeightfieldRecord, heightfield_distance, heightfield_local, heightfield_reaches,
}

const BRICK: u32 = 8u;
const GROUP: u32 = 128u;
const MAX_LEVELS: u32 = 8u;

struct ComposeJob {
    tile: vec3<i32>,
    level: u32,
    first: vec3<f32>,
    word: u32,
}

struct ComposeParams {
    // Per level: texel size, band, quantum, dilation.
    levels: array<vec4<f32>, MAX_LEVELS>,
    slot_count: u32,
    job_count: u32,
    heightfield_count: u32,
}

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var atlas: texture_3d<f32>;
@group(0) @binding(7) var brick_table: texture_2d<u32>;
@group(0) @binding(2) var<storage, read> jobs: array<ComposeJob>;
@group(0) @binding(3) var<uniform> params: ComposeParams;
@group(0) @binding(4) var<storage, read_write> field: array<u32>;
@group(0) @binding(5) var<storage, read> heightfields: array<HeightfieldRecord>;
@group(0) @binding(6) var heights: texture_2d<f32>;

var<workgroup> kept: array<u32, GROUP>;
var<workgroup> kept_count: atomic<u32>;
var<workgroup> kept_n: u32;

// Whether record `o` can change the brick whose texel centres span [lo, hi].
fn reaches(o: DistanceFieldObject, job: ComposeJob, lo: vec3<f32>, hi: vec3<f32>, reach: f32) -> bool {
    if !casts_occlusion(o) || ao_transmission(o) != 0.0 {
        return false;
    }
    let ball = bounding_sphere(o, job.tile, vec3<f32>(0.0));
    if ball.w < 0.0 {
        return true;
    }
    return length(clamp(ball.xyz, lo, hi) - ball.xyz) <= ball.w + reach;
}

// The stored byte of distance `d`: `store(Unorm8, d, band)` of the model.
fn encode(d: f32, band: f32, quantum: f32) -> u32 {
    let x = clamp(d, -band, band) - quantum;
    let u = clamp(0.5 + 0.5 * x / band, 0.0, 1.0);
    return u32(floor(u * 255.0 + 0.5));
}

// The distances of the heightfields reaching the brick at this invocation's four texels.
fn terrain_distances(
    job: ComposeJob,
    lo: vec3<f32>,
    hi: vec3<f32>,
    base: vec3<u32>,
    texel: f32,
    reach: f32,
) -> vec4<f32> {
    var d = vec4<f32>(reach);
    for (var t = 0u; t < params.heightfield_count; t++) {
        let h = heightfields[t];
        let first = heightfield_local(h, job.tile, job.first);
        if !heightfield_reaches(h, first, first + (hi - lo), reach) {
            continue;
        }
        for (var i = 0u; i < 4u; i++) {
            let p = first + vec3<f32>(base + vec3<u32>(i, 0u, 0u)) * texel;
            d[i] = min(d[i], heightfield_distance(h, heights, p));
        }
    }
    return d;
}

@compute @workgroup_size(128, 1, 1)
fn compose(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) index: u32) {
    if group.x >= params.job_count {
        return;
    }
    let job = jobs[group.x];
    let level = params.levels[job.level];
    let texel = level.x;
    let band = level.y;
    let quantum = level.z;
    let dilation = level.w;
    let lo = job.first;
    let hi = job.first + vec3<f32>(f32(BRICK - 1u) * texel);
    // This invocation's four texels: x = 4 (index % 2) .. + 3, y, z.
    let base = vec3<u32>(4u * (index % 2u), (index / 2u) % BRICK, index / 16u);
    let reach = band + dilation;
    var d = vec4<f32>(reach);
    for (var start = 0u; start < params.slot_count; start += GROUP) {
        if index == 0u {
            atomicStore(&kept_count, 0u);
        }
        workgroupBarrier();
        let slot = start + index;
        if slot < params.slot_count && reaches(objects[slot], job, lo, hi, reach) {
            kept[atomicAdd(&kept_count, 1u)] = slot;
        }
        workgroupBarrier();
        if index == 0u {
            kept_n = atomicLoad(&kept_count);
        }
        workgroupBarrier();
        let n = kept_n;
        for (var k = 0u; k < n; k++) {
            let o = objects[kept[k]];
            for (var i = 0u; i < 4u; i++) {
                let p = job.first + vec3<f32>(base + vec3<u32>(i, 0u, 0u)) * texel;
                d[i] = min(d[i], object_distance(o, p, job.tile, vec3<f32>(0.0), atlas, brick_table));
            }
        }
        workgroupBarrier();
    }
    d = min(d, terrain_distances(job, lo, hi, base, texel, reach));
    var word = 0u;
    for (var i = 0u; i < 4u; i++) {
        word |= encode(d[i] - dilation, band, quantum) << (8u * i);
    }
    field[job.word + index] = word;
}
