// Billboard reflections' trace (`bevy_penumbra_cinematic::reflections`): for each
// G-buffer pixel (at full or half resolution), the mirror ray from the normal and the
// view vector is intersected with every billboard; the nearest `max_layers` hits whose
// GGX footprint overlaps the image are sampled over that footprint and composited front
// to back into premultiplied radiance (cd/m²) and coverage — the specular layer that
// Penumbra's lighting pass adds under Bevy's environment BRDF. Reflection shadows: one
// soft march along the mirror ray through the distance-field scene's objects dims each
// hit by its visibility.
// Each pixel tests only its tile's billboards (`reflections/cull.wgsl`), which changes
// no result, and its shadow march gathers from its tile's casters, or from the caster
// grid (`reflections/spheres.wgsl`) where the tile's list overflowed or is long. CPU model: `penumbra_cinematic_core::reflections::pass::reflect_pixel`.

#import penumbra::reflections::common::{
    Lobe, MAX_LAYERS, MAX_TAPS, MIN_SHADOW_STEP, TILE, atlas, billboards, brick_table, camera_position,
    caster_record, casts, images, images_sampler, objects, settings, spheres,
    surface_sample, tile_lists, tile_record,
}
#import penumbra::reflections::types::{
    GRID_FRAME_CELL, GRID_FRAME_DIMS, GRID_FRAME_LO, GRID_LARGE_COUNT, GRID_MAX_RADIUS,
    GRID_OVER_LIST, GpuBillboard, grid_items, grid_large, grid_offsets,
}
#import penumbra::df::distance::object_distance

// Most objects one segment of a pixel's reflection-shadow march keeps after its cull;
// more: it marches them all there (`pass::MAX_SHADOW_CASTERS`).
const MAX_SHADOW_CASTERS: u32 = 32u;
// Segments of the march, each with its own objects (`pass::SHADOW_SEGMENTS`).
const SHADOW_SEGMENTS: u32 = 8u;

struct FootprintHit {
    t: f32,
    index: u32,
    uv: vec2<f32>,
    axis_a: vec2<f32>,
    axis_b: vec2<f32>,
}

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
}

@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32) -> FullscreenVertexOutput {
    let uv = vec2<f32>(f32(vertex_index >> 1u), f32(vertex_index & 1u)) * 2.0;
    return FullscreenVertexOutput(vec4(uv * vec2(2.0, -2.0) + vec2(-1.0, 1.0), 0.0, 1.0));
}


@fragment
fn fragment(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    let trace_pixel = vec2<i32>(in.position.xy);
    let surface = surface_sample(trace_pixel);
    if !surface.valid {
        return vec4(0.0);
    }
    return reflect_billboards(vec2<u32>(trace_pixel), surface.position, surface.lobe);
}

// The hit of the lobe on billboard `index`; `t = -1` when it misses.
fn footprint_hit(index: u32, origin: vec3<f32>, lobe: Lobe) -> FootprintHit {
    var hit = FootprintHit(-1.0, index, vec2(0.0), vec2(0.0), vec2(0.0));
    let b = billboards[index];
    let n = cross(b.half_x, b.half_y);
    let facing = dot(lobe.dir, n);
    if !(facing < 0.0) || (b.layers & settings.view_layers) == 0u {
        return hit;
    }
    let t = dot(b.center - origin, n) / facing;
    if !(t > 0.0 && t <= settings.max_distance) {
        return hit;
    }
    let n2 = dot(n, n);
    let du = cross(b.half_y, n) * (0.5 / n2);
    let dv = cross(n, b.half_x) * (-0.5 / n2);
    let p = origin + lobe.dir * t - b.center;
    let uv = vec2(dot(p, du), dot(p, dv)) + 0.5;
    let oa = lobe.major * t;
    let ob = lobe.minor * t;
    let pa = oa - lobe.dir * (dot(oa, n) / facing);
    let pb = ob - lobe.dir * (dot(ob, n) / facing);
    let axis_a = vec2(dot(pa, du), dot(pa, dv));
    let axis_b = vec2(dot(pb, du), dot(pb, dv));
    let reach = abs(axis_a) + abs(axis_b);
    if all(uv >= -reach) && all(uv <= vec2(1.0) + reach) {
        hit = FootprintHit(t, index, uv, axis_a, axis_b);
    }
    return hit;
}

// The fraction of the box [c − e, c + e] inside [0, 1].
fn box_coverage(c: f32, e: f32) -> f32 {
    if e <= 1e-7 {
        return select(0.0, 1.0, c >= 0.0 && c <= 1.0);
    }
    return min((clamp(c + e, 0.0, 1.0) - clamp(c - e, 0.0, 1.0)) / (2.0 * e), 1.0);
}

// The premultiplied image over a hit's footprint: taps along its long axis, spread so
// that the result varies continuously with the footprint's shape
// (`penumbra_cinematic_core::reflections::pass::sample_footprint`).
fn sample_footprint(layer: u32, hit: FootprintHit) -> vec4<f32> {
    let size = vec2<f32>(settings.texture_size);
    let ta = hit.axis_a * size;
    let tb = hit.axis_b * size;
    var long = length(tb);
    var short = length(ta);
    var long_uv = hit.axis_b;
    var short_uv = hit.axis_a;
    if length(ta) >= length(tb) {
        long = length(ta);
        short = length(tb);
        long_uv = hit.axis_a;
        short_uv = hit.axis_b;
    }
    var taps = 1u;
    if long > short * 1.0001 {
        taps = clamp(settings.taps, 1u, MAX_TAPS);
    }
    let n = f32(taps);
    let half = max(short, long / n);
    let lod = log2(max(2.0 * half, 1.0));
    var share = 1.0;
    if long > 0.0 {
        share = half / long;
    }
    let reach = abs(short_uv) + abs(long_uv) * share;
    var sum = vec4(0.0);
    for (var k = 0u; k < taps; k += 1u) {
        var at = 0.0;
        if taps > 1u {
            at = 2.0 * f32(k) / (n - 1.0) - 1.0;
        }
        let uv = hit.uv + long_uv * ((1.0 - share) * at);
        let cover = box_coverage(uv.x, reach.x) * box_coverage(uv.y, reach.y);
        if cover > 0.0 {
            sum += textureSampleLevel(images, images_sampler, uv, layer, lod) * cover;
        }
    }
    return sum / n;
}

// The nearest hits composited front to back: premultiplied radiance and coverage.
fn reflect_billboards(trace_pixel: vec2<u32>, origin: vec3<f32>, lobe: Lobe) -> vec4<f32> {
    let k = clamp(settings.max_layers, 1u, MAX_LAYERS);
    var hits: array<FootprintHit, MAX_LAYERS>;
    var count = 0u;
    // The tile's list of billboards, or every billboard.
    var listed = settings.billboard_count;
    var list_start = 0u;
    var use_list = false;
    if settings.tile_capacity > 0u {
        let base = tile_record(trace_pixel / TILE);
        if tile_lists[base] <= settings.tile_capacity {
            listed = tile_lists[base];
            list_start = base + 1u;
            use_list = true;
        }
    }
    for (var m = 0u; m < listed; m += 1u) {
        var i = m;
        if use_list {
            i = tile_lists[list_start + m];
        }
        let hit = footprint_hit(i, origin, lobe);
        if hit.t < 0.0 {
            continue;
        }
        // Insertion into the sorted list (distance, then index).
        var at = count;
        for (var j = 0u; j < count; j += 1u) {
            if hit.t < hits[j].t || (hit.t == hits[j].t && hit.index < hits[j].index) {
                at = j;
                break;
            }
        }
        if at >= k {
            continue;
        }
        var j = min(count, k - 1u);
        while j > at {
            hits[j] = hits[j - 1u];
            j -= 1u;
        }
        hits[at] = hit;
        count = min(count + 1u, k);
    }
    let cone = max(length(lobe.major) * settings.shadow_cone, settings.shadow_softness);
    var facing: array<f32, MAX_LAYERS>;
    for (var j = 0u; j < count; j += 1u) {
        let b = billboards[hits[j].index];
        facing[j] = abs(dot(lobe.dir, normalize(cross(b.half_x, b.half_y))));
    }
    let visibility = shadow_march(origin, lobe.dir, &hits, &facing, count, cone, tile_casters(trace_pixel));
    var colour = vec3(0.0);
    var transmittance = 1.0;
    for (var j = 0u; j < count; j += 1u) {
        let b = billboards[hits[j].index];
        let texel = sample_footprint(b.layer, hits[j]);
        colour += transmittance * texel.rgb * (b.emissive * visibility[j]);
        transmittance *= 1.0 - clamp(texel.a, 0.0, 1.0);
    }
    // The layer's largest f16 (`pass::MAX_REFLECTED_RADIANCE`): an emissive above it
    // would store infinity.
    return vec4(min(colour, vec3(65504.0)), 1.0 - transmittance);
}

// The objects a pixel's shadow march gathers from: its tile's caster list, or every
// object slot (no lists, or the tile's is over its capacity).
struct Candidates {
    start: u32,
    count: u32,
    listed: bool,
}

fn tile_casters(trace_pixel: vec2<u32>) -> Candidates {
    var c = Candidates(0u, settings.object_count, false);
    if settings.caster_capacity > 0u {
        let at = caster_record(tile_record(trace_pixel / TILE));
        let n = tile_lists[at];
        if n <= settings.caster_capacity {
            c = Candidates(at + 1u, n, true);
        }
    }
    return c;
}

// The object slot of candidate `m`.
fn candidate(c: Candidates, m: u32) -> u32 {
    if c.listed {
        return tile_lists[c.start + m];
    }
    return m;
}

// Whether the caster of camera-relative `sphere` (w −1: unbounded; −2: no caster) comes
// within `reach` of the segment from `a` along `ab` (`pass::keeps_caster`).
fn keeps_caster(sphere: vec4<f32>, a: vec3<f32>, ab: vec3<f32>, reach: f32) -> bool {
    if sphere.w < -1.5 {
        return false;
    }
    if sphere.w < 0.0 {
        return true;
    }
    let r = sphere.w + reach;
    let l2 = dot(ab, ab);
    var h = 0.0;
    if l2 > 0.0 {
        h = clamp(dot(sphere.xyz - a, ab) / l2, 0.0, 1.0);
    }
    return length(sphere.xyz - a - ab * h) < r + (r * 1e-4 + 1e-4);
}

// The live shadow-casting candidates whose bounding sphere comes within `cone · t1` of
// the ray between `t0` and `t1` (`pass::shadow_casters`): farther, an object never dims
// a hit there. Returns how many (in `list`), or MAX_SHADOW_CASTERS + 1: march every
// candidate. A tile without a list, or with a long one, gathers from the caster grid
// when there is one.
fn gather_casters(
    origin: vec3<f32>,
    dir: vec3<f32>,
    t0: f32,
    t1: f32,
    cone: f32,
    c: Candidates,
    list: ptr<function, array<u32, MAX_SHADOW_CASTERS>>,
) -> u32 {
    let a = (origin + dir * t0) - camera_position();
    let ab = (origin + dir * t1) - (origin + dir * t0);
    // The grid where the tile has no list, or a long one (the same set either way: the
    // list holds every object a segment of the tile can keep).
    if settings.caster_grid != 0u && (!c.listed || c.count > GRID_OVER_LIST) {
        let n = gather_from_grid(a, ab, cone * t1, list);
        if n != GRID_TOO_WIDE {
            return n;
        }
    }
    var n = 0u;
    for (var m = 0u; m < c.count; m += 1u) {
        let i = candidate(c, m);
        if !keeps_caster(spheres[i], a, ab, cone * t1) {
            continue;
        }
        if n == MAX_SHADOW_CASTERS {
            return MAX_SHADOW_CASTERS + 1u;
        }
        (*list)[n] = i;
        n += 1u;
    }
    return n;
}

// `gather_from_grid`: the segment's box spans more cells than there are objects.
const GRID_TOO_WIDE: u32 = 0xffffffffu;

// Adds object `i` to `list` if kept; false once more than MAX_SHADOW_CASTERS are.
fn keep_from_grid(
    i: u32,
    a: vec3<f32>,
    ab: vec3<f32>,
    reach: f32,
    list: ptr<function, array<u32, MAX_SHADOW_CASTERS>>,
    n: ptr<function, u32>,
) -> bool {
    if !keeps_caster(spheres[i], a, ab, reach) {
        return true;
    }
    if *n == MAX_SHADOW_CASTERS {
        return false;
    }
    (*list)[*n] = i;
    *n += 1u;
    return true;
}

// The segment's casters from the caster grid (`grid::CasterGrid::gather`): the large
// ones, then those listed in the cells of the segment's box widened by `reach` and the
// largest listed radius. The same set as from every object, in another order.
fn gather_from_grid(
    a: vec3<f32>,
    ab: vec3<f32>,
    reach: f32,
    list: ptr<function, array<u32, MAX_SHADOW_CASTERS>>,
) -> u32 {
    let g = settings.caster_grid;
    let dims = vec3(tile_lists[g + GRID_FRAME_DIMS], tile_lists[g + GRID_FRAME_DIMS + 1u], tile_lists[g + GRID_FRAME_DIMS + 2u]);
    let lo = vec3(bitcast<f32>(tile_lists[g + GRID_FRAME_LO]), bitcast<f32>(tile_lists[g + GRID_FRAME_LO + 1u]), bitcast<f32>(tile_lists[g + GRID_FRAME_LO + 2u]));
    let cell = bitcast<f32>(tile_lists[g + GRID_FRAME_CELL]);
    let widen = (bitcast<f32>(tile_lists[g + GRID_MAX_RADIUS]) + reach) * 1.001 + 1e-3;
    let b = a + ab;
    let lo_f = (min(a, b) - widen - lo) / cell;
    let hi_f = (max(a, b) + widen - lo) / cell;
    let d = vec3<f32>(dims);
    // No cell: none listed, or the box is off the grid (NaN compares false: too wide).
    let empty = dims.x == 0u || any(hi_f < vec3(0.0)) || any(lo_f >= d);
    var first = vec3(0u);
    var last = vec3(0u);
    if !empty {
        if !(all(lo_f == lo_f) && all(hi_f == hi_f)) {
            return GRID_TOO_WIDE;
        }
        first = vec3<u32>(max(lo_f, vec3(0.0)));
        last = min(vec3<u32>(min(hi_f, d - 1.0)), dims - 1u);
        let span = vec3<f32>(last - first + 1u);
        if span.x * span.y * span.z > f32(settings.object_count) {
            return GRID_TOO_WIDE;
        }
    }
    var n = 0u;
    let large = grid_large(g, settings.object_count);
    for (var k = 0u; k < tile_lists[g + GRID_LARGE_COUNT]; k += 1u) {
        if !keep_from_grid(tile_lists[large + k], a, ab, reach, list, &n) {
            return MAX_SHADOW_CASTERS + 1u;
        }
    }
    if empty {
        return n;
    }
    let offsets = grid_offsets(g);
    let items = grid_items(g);
    for (var z = first.z; z <= last.z; z += 1u) {
        for (var y = first.y; y <= last.y; y += 1u) {
            let row = (z * dims.y + y) * dims.x;
            // A row's cells are consecutive: their items too.
            let end = tile_lists[offsets + row + last.x + 1u];
            for (var m = tile_lists[offsets + row + first.x]; m < end; m += 1u) {
                if !keep_from_grid(tile_lists[items + m], a, ab, reach, list, &n) {
                    return MAX_SHADOW_CASTERS + 1u;
                }
            }
        }
    }
    return n;
}

// The distance (metres) from world point `p` to the nearest of the gathered objects
// (every live shadow-casting candidate when `count` is past the list).
fn scene_distance(
    p: vec3<f32>,
    c: Candidates,
    list: ptr<function, array<u32, MAX_SHADOW_CASTERS>>,
    count: u32,
) -> f32 {
    let relative = p - camera_position();
    var d = 3.4e38;
    if count > MAX_SHADOW_CASTERS {
        for (var m = 0u; m < c.count; m += 1u) {
            let i = candidate(c, m);
            if casts(i) {
                d = min(d, object_distance(objects[i], relative, settings.camera_tile, settings.camera_offset, atlas, brick_table));
            }
        }
        return d;
    }
    for (var k = 0u; k < count; k += 1u) {
        let o = objects[(*list)[k]];
        d = min(d, object_distance(o, relative, settings.camera_tile, settings.camera_offset, atlas, brick_table));
    }
    return d;
}

// Where segment `k` of a march to `t_end` ends (`pass::segment_ends`: exact).
fn segment_end(t_end: f32, k: u32) -> f32 {
    return t_end * (0.125 * f32(k + 1u));
}

// Reflection shadows: each hit's visibility from one soft march along the ray, counting
// only surfaces in front of the next billboard's plane
// (`penumbra_cinematic_core::reflections::pass::shadow_march`).
fn shadow_march(
    origin: vec3<f32>,
    dir: vec3<f32>,
    hits: ptr<function, array<FootprintHit, MAX_LAYERS>>,
    facing: ptr<function, array<f32, MAX_LAYERS>>,
    count: u32,
    cone: f32,
    candidates: Candidates,
) -> array<f32, MAX_LAYERS> {
    var out = array<f32, MAX_LAYERS>(1.0, 1.0, 1.0, 1.0);
    if settings.shadow_steps == 0u || settings.object_count == 0u || count == 0u {
        return out;
    }
    // The ray to the last hit in SHADOW_SEGMENTS equal parts, each marched through the
    // objects near it, gathered when the march reaches it (`pass::march_segments`).
    let t_end = (*hits)[count - 1u].t;
    var casters: array<u32, MAX_SHADOW_CASTERS>;
    var caster_count = 0u;
    var gathered = SHADOW_SEGMENTS;
    var k = 0u;
    var t = settings.shadow_bias;
    var v = 1.0;
    var j = 0u;
    for (var step = 0u; step < settings.shadow_steps; step += 1u) {
        while j < count && t >= (*hits)[j].t {
            out[j] = v;
            j += 1u;
        }
        if j >= count || v <= 0.0 {
            break;
        }
        while k + 1u < SHADOW_SEGMENTS && t >= segment_end(t_end, k) {
            k += 1u;
        }
        if gathered != k {
            var t0 = 0.0;
            if k > 0u {
                t0 = segment_end(t_end, k - 1u);
            }
            caster_count = gather_casters(origin, dir, t0, segment_end(t_end, k), cone, candidates, &casters);
            gathered = k;
        }
        let d = scene_distance(origin + dir * t, candidates, &casters, caster_count);
        // Only surfaces surely in front of the next billboard's plane occlude it.
        if d < ((*hits)[j].t - t) * (*facing)[j] {
            v = min(v, clamp(d / (cone * t), 0.0, 1.0));
        }
        let next = t + max(d, MIN_SHADOW_STEP);
        // A step stops at its segment's end: the next segment's objects are seen from
        // its start.
        if k + 1u < SHADOW_SEGMENTS && next > segment_end(t_end, k) {
            t = segment_end(t_end, k);
        } else {
            t = next;
        }
    }
    for (; j < count; j += 1u) {
        out[j] = v;
    }
    return out;
}
