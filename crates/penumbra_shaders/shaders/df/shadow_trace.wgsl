// The distance-field shadow-mask pass for one light and one view: per 8×8 pixel tile,
// the light-culled objects are culled again against the round cone (the hull of the
// tile's bounding ball and the light's end ball) that contains every pixel's shadow
// cone, 64 at a time into workgroup memory; each pixel then marches the survivors
// (`penumbra::df::shadow`). A tile with a pixel whose G-buffer normal hides the light
// lists them once more before the march, for that pixel to read the normal of the caster
// field it lies on (`caster_field_normal`: the triangles' facing where a normal map or
// smooth shading turned the G-buffer's away). Terrains (`camera_tile.w` heightfield records,
// `df/heightfield.wgsl`) are marched by every pixel whose shadow ray's box, grown by the
// cone's end radius, meets theirs. Writes visibility (1 lit, 0 shadowed) for every
// pixel; background pixels (depth 0) get 1. CPU model:
// `penumbra_reference::shadow_mask::pixel_visibility_with_terrain`.
#define_import_path penumbra::df::shadow_trace

#import penumbra::df::object::{DistanceFieldObject, FLAG_SHADING_APART, TILE_SIZE}
#import penumbra::df::heightfield::{HeightfieldRecord, heightfield_distance}
#import penumbra::df::shadow::{
    FIELD_NORMAL_MIN_AGREEMENT, FIELD_NORMAL_MIN_FACING, FIELD_NORMAL_MIN_FACING_SHADED,
    FACE_NORMAL_MIN_AGREEMENT, FACE_NORMAL_PLANE_SIN, FACE_DEPTH_TOLERANCE, FLAT_SHADED_SIN, NO_FIELD_NORMAL,
    inside_analytic, seen_from_inside,
    PENUMBRA_MIN_STEP, ShadowLight, ShadowRay, bounding_sphere, caster_field_normal, casts_shadows,
    cull_slack,
    facing_the_eye, finish_visibility, gbuffer_normal, horizon_visibility, is_directional, march_object,
    march_start, object_in_cone, penumbra_visibility, round_cone_distance, shadow_ray,
    traces_point,
}
#import penumbra::lighting::msaa::MSAA_SAMPLE_POSITIONS
#import penumbra::df::shadow_grid::{
    GRID_SIZE, MAX_CELLS, ShadowGridRead, ShadowGridView, cell_range, from_order_key,
    grid_frame, grid_light, light_space_disc, order_key, range_cells,
}

struct ShadowTraceView {
    view_from_clip: mat4x4<f32>,
    // Columns of the camera's world-from-view rotation (xyz).
    world_from_view: array<vec4<f32>, 3>,
    // xyz: the camera's tile; w: terrains bound (`heightfields`).
    camera_tile: vec4<i32>,
    // xyz: the camera's position within its tile.
    camera_offset: vec4<f32>,
    // x, y: mask size in pixels; z: pixels per mask texel along each axis (1 full
    // resolution, 2 half: texel (i, j) traces full-resolution pixel (2i, 2j)); w: 1 when
    // `gbuffer` holds the view's normals (the surface's own shadow), 0 when not.
    size: vec4<u32>,
    // The view's viewport in the frame buffer: x, y (where its pixels are read from the
    // prepass textures, which are the render target's size), width, height (full
    // resolution; the mask is the viewport's size).
    viewport: vec4<u32>,
}

// `size.w`'s bits (`penumbra_df_core::shadow::TRACE_*`): `gbuffer` holds the view's
// normals; `face_normals` and `face_depth` hold its face-normal prepass.
const TRACE_GBUFFER_NORMALS: u32 = 1u;
const TRACE_FACE_NORMALS: u32 = 2u;

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
// The light's culled slots and (first word of) their count.
@group(0) @binding(1) var<storage, read> light_objects: array<u32>;
@group(0) @binding(2) var<storage, read> light_object_count: array<u32>;
@group(0) @binding(3) var atlas: texture_3d<f32>;
#ifdef PENUMBRA_SAMPLE_TRACE
// Deferred MSAA's per-sample trace: the multisampled reverse-Z depth and G-buffer; the
// threads cover the samples of the pixels the classification shades per sample
// (class 2), and `mask` is twice the view's size (`msaa_sample_texel`).
@group(0) @binding(4) var depth_texture: texture_depth_multisampled_2d;
@group(0) @binding(12) var gbuffer: texture_multisampled_2d<u32>;
@group(0) @binding(15) var pixel_class: texture_2d<u32>;
// The brick table of bricked volumes (`penumbra::df::distance`).
@group(0) @binding(16) var brick_table: texture_2d<u32>;
#else
// Reverse-Z depth (the prepass depth, bound as an unfilterable float texture).
@group(0) @binding(4) var depth_texture: texture_2d<f32>;
// Bevy's deferred G-buffer (Rgba32Uint; the normal in `.a`), read with
// TRACE_GBUFFER_NORMALS.
@group(0) @binding(12) var gbuffer: texture_2d<u32>;
@group(0) @binding(15) var brick_table: texture_2d<u32>;
// The face-normal prepass (`bevy_penumbra_df::face_normals`): each pixel's triangle
// normal by its winding (w 1 where drawn) and that pass's own reverse-Z depth, read with
// TRACE_FACE_NORMALS.
@group(0) @binding(16) var face_normals: texture_2d<f32>;
@group(0) @binding(17) var face_depth: texture_2d<f32>;
#endif
@group(0) @binding(5) var<uniform> view: ShadowTraceView;
@group(0) @binding(6) var<uniform> light: ShadowLight;
@group(0) @binding(7) var mask: texture_storage_2d<r32float, write>;
// Directional lights: the light-space grid of the light's casters
// (`penumbra::df::shadow_grid`); `grid_view.u.w` is 1 when it is in use.
@group(0) @binding(8) var<storage, read> grid: ShadowGridRead;
@group(0) @binding(9) var<storage, read> grid_items: array<u32>;
@group(0) @binding(10) var<storage, read> grid_large: array<u32>;
@group(0) @binding(11) var<uniform> grid_view: ShadowGridView;
@group(0) @binding(13) var<storage, read> heightfields: array<HeightfieldRecord>;
@group(0) @binding(14) var heights: texture_2d<f32>;

const TILE_PIXELS: u32 = 64u;

var<workgroup> tile_min: array<atomic<u32>, 3>;
var<workgroup> tile_max: array<atomic<u32>, 3>;
var<workgroup> tile_slots: array<u32, 64>;
var<workgroup> tile_spheres: array<vec4<f32>, 64>;
var<workgroup> tile_count: atomic<u32>;
// Whether a pixel of the tile has the light partly below its G-buffer normal's horizon
// (then the tile reads its casters' fields for their own normals).
var<workgroup> tile_hidden: atomic<u32>;
var<workgroup> tile_reads_fields: u32;
var<workgroup> tile_n: u32;
var<workgroup> total_n: u32;
// The tile's candidates: 0 the light's list, 1 the grid (large casters, then the casters
// of the cells in `tile_cells`).
var<workgroup> tile_mode: u32;
var<workgroup> tile_cells: vec4<i32>;
var<workgroup> tile_large: u32;

// What a thread traces: a frame-buffer point, its reverse-Z depth (0: nothing), its
// G-buffer normal word and its triangle's normal (0: unknown); `store`: whether the
// thread writes its mask texel.
struct TracePoint {
    screen: vec2<f32>,
    depth: f32,
    normal_word: u32,
    face: vec3<f32>,
    store: bool,
}

#ifdef PENUMBRA_SAMPLE_TRACE
// Sample `(gid.x & 1) | (gid.y & 1) << 1` of pixel `gid / 2`, traced where the pixel is
// shaded per sample.
fn trace_point(gid: vec2<u32>, inside: bool) -> TracePoint {
    let local = vec2<i32>(gid / 2u);
    let pixel = local + vec2<i32>(view.viewport.xy);
    let i = (gid.x & 1u) | ((gid.y & 1u) << 1u);
    if !inside || textureLoad(pixel_class, pixel, 0).r != 2u {
        return TracePoint(vec2<f32>(0.0), 0.0, 0u, vec3<f32>(0.0), false);
    }
    return TracePoint(
        vec2<f32>(local) + MSAA_SAMPLE_POSITIONS[i],
        textureLoad(depth_texture, pixel, i32(i)),
        textureLoad(gbuffer, pixel, i32(i)).a,
        vec3<f32>(0.0),
        true,
    );
}
#else
// The centre of the viewport's full-resolution pixel `gid × stride`.
fn trace_point(gid: vec2<u32>, inside: bool) -> TracePoint {
    let local = vec2<i32>(gid * max(view.size.z, 1u));
    let pixel = local + vec2<i32>(view.viewport.xy);
    if !inside {
        return TracePoint(vec2<f32>(0.0), 0.0, 0u, vec3<f32>(0.0), false);
    }
    var word = 0u;
    if (view.size.w & TRACE_GBUFFER_NORMALS) != 0u {
        word = textureLoad(gbuffer, pixel, 0).a;
    }
    let depth = textureLoad(depth_texture, pixel, 0).r;
    return TracePoint(vec2<f32>(local) + 0.5, depth, word, pixel_face_normal(pixel, depth), true);
}

// The triangle normal the face-normal prepass drew at `pixel`, where it drew the surface
// the G-buffer holds (reverse-Z depths within FACE_DEPTH_TOLERANCE:
// `penumbra_df_core::shadow::face_normal_trusted`); else 0.
fn pixel_face_normal(pixel: vec2<i32>, depth: f32) -> vec3<f32> {
    if (view.size.w & TRACE_FACE_NORMALS) == 0u || depth <= 0.0 {
        return vec3<f32>(0.0);
    }
    let face = textureLoad(face_normals, pixel, 0);
    let face_depth = textureLoad(face_depth, pixel, 0).r;
    if face.w < 0.5 || abs(face_depth - depth) > FACE_DEPTH_TOLERANCE * depth {
        return vec3<f32>(0.0);
    }
    return face.xyz;
}
#endif

// Camera-relative world position of viewport point `screen` at reverse-Z `depth`.
fn position_from_depth(screen: vec2<f32>, depth: f32) -> vec3<f32> {
    let uv = screen / vec2<f32>(max(view.viewport.zw, vec2<u32>(1u)));
    let ndc = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let v = view.view_from_clip * ndc;
    let q = v.xyz / v.w;
    return view.world_from_view[0].xyz * q.x + view.world_from_view[1].xyz * q.y
        + view.world_from_view[2].xyz * q.z;
}

// The depth-buffer points of viewport pixel `pixel`'s four neighbours (x−, x+, y−, y+)
// less its own point `p`; w: 1 where the neighbour lies in the viewport on a surface,
// else 0. None under deferred MSAA's per-sample trace (its samples are no pixel grid).
fn depth_neighbours(pixel: vec2<i32>, screen: vec2<f32>, p: vec3<f32>) -> array<vec4<f32>, 4> {
    var out: array<vec4<f32>, 4>;
#ifndef PENUMBRA_SAMPLE_TRACE
    let lo = vec2<i32>(view.viewport.xy);
    let hi = lo + vec2<i32>(view.viewport.zw);
    for (var i = 0; i < 4; i += 1) {
        var o = vec2<i32>(0);
        o[i / 2] = select(-1, 1, (i & 1) == 1);
        let q = pixel + o;
        if any(q < lo) || any(q >= hi) {
            continue;
        }
        let d = textureLoad(depth_texture, q, 0).r;
        if !(d > 0.0) {
            continue;
        }
        out[i] = vec4<f32>(position_from_depth(screen + vec2<f32>(o), d) - p, 1.0);
    }
#endif
    return out;
}

// Whether the pixel's G-buffer normal (turned to face the eye) is its face's own — a
// flat-shaded face, not a smooth or normal-mapped normal: along each screen axis one of
// its two neighbours' depth-buffer points (`depth_neighbours`) lies in its tangent plane,
// within FLAT_SHADED_SIN (one, not the nearer: on a face two pixels tall each pixel's
// other neighbour is another face). CPU model: `shadow_mask::flat_shaded`.
fn flat_shaded(neighbours: array<vec4<f32>, 4>, normal: vec3<f32>) -> bool {
    var nb = neighbours;
    for (var axis = 0; axis < 2; axis += 1) {
        var in_plane = false;
        for (var side = 0; side < 2; side += 1) {
            let e = nb[axis * 2 + side];
            in_plane = in_plane || (e.w > 0.0 && abs(dot(e.xyz, normal)) <= FLAT_SHADED_SIN * length(e.xyz));
        }
        if !in_plane {
            return false;
        }
    }
    return true;
}

// The normal of the face the pixel sees, from its depth-buffer neighbours: along each
// screen axis the central difference of the two (the one neighbour's difference where
// the other is missing), their cross product turned to `normal`'s side; zero where an
// axis has no neighbour, the points are degenerate, or a neighbour lies further than
// FACE_NORMAL_PLANE_SIN from the plane (a crease or silhouette between them). CPU model:
// `shadow_mask::face_normal`.
fn depth_face_normal(neighbours: array<vec4<f32>, 4>, normal: vec3<f32>) -> vec3<f32> {
    var nb = neighbours;
    var edges: array<vec3<f32>, 2>;
    for (var axis = 0; axis < 2; axis += 1) {
        let a = nb[axis * 2];
        let b = nb[axis * 2 + 1];
        if a.w > 0.0 && b.w > 0.0 {
            edges[axis] = b.xyz - a.xyz;
        } else if a.w > 0.0 {
            edges[axis] = -a.xyz;
        } else if b.w > 0.0 {
            edges[axis] = b.xyz;
        } else {
            return vec3<f32>(0.0);
        }
    }
    let c = cross(edges[0], edges[1]);
    if !(dot(c, c) > 1e-30) {
        return vec3<f32>(0.0);
    }
    var n = normalize(c);
    if dot(n, normal) < 0.0 {
        n = -n;
    }
    for (var i = 0; i < 4; i += 1) {
        let e = nb[i];
        if e.w > 0.0 && abs(dot(e.xyz, n)) > FACE_NORMAL_PLANE_SIN * length(e.xyz) {
            return vec3<f32>(0.0);
        }
    }
    return n;
}

// The terrains' visibility along `ray` from camera-relative `p`
// (`shadow_mask::terrain_visibility`): each step at least half a terrain cell across,
// so a ray grazing a slope still crosses the terrain within the step budget.
fn terrain_visibility(p: vec3<f32>, ray: ShadowRay) -> f32 {
    var visibility = 1.0;
    for (var i = 0u; i < u32(view.camera_tile.w); i += 1u) {
        let h = heightfields[i];
        let local = vec3<f32>(view.camera_tile.xyz - h.tile) * TILE_SIZE + view.camera_offset.xyz + p;
        let end = local + ray.dir * ray.t_max;
        let grow = ray.t_max * ray.tan_half;
        let lo = vec3<f32>(h.origin.x, h.bounds.z, h.origin.y);
        let hi = vec3<f32>(h.origin.x + h.extent.x, h.bounds.w, h.origin.y + h.extent.y);
        if any(min(local, end) - grow > hi) || any(max(local, end) + grow < lo) {
            continue;
        }
        let cells = h.extent / vec2<f32>(h.size - vec2<u32>(1u));
        let min_step = 0.5 * min(cells.x, cells.y) / max(length(ray.dir.xz), 1e-3);
        var t = light.bias;
        var v = 1.0;
        for (var step = 0u; step < light.max_steps; step += 1u) {
            if t >= ray.t_max {
                break;
            }
            let d = heightfield_distance(h, heights, local + ray.dir * t);
            let cone = max(t * ray.tan_half, 1e-6);
            v = min(v, d / cone);
            if v <= -1.0 {
                break;
            }
            t += max(max(abs(d), min_step), cone * PENUMBRA_MIN_STEP);
        }
        visibility = min(visibility, penumbra_visibility(v));
    }
    return visibility;
}

@compute @workgroup_size(8, 8, 1)
fn trace(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    // Every workgroup variable is written before it is read: Bevy's compute pipelines do
    // not zero-initialize workgroup memory (`zero_initialize_workgroup_memory: false`),
    // and a garbage `tile_count` indexed `tile_slots` out of bounds (a lavapipe crash).
    if li == 0u {
        for (var i = 0u; i < 3u; i += 1u) {
            atomicStore(&tile_min[i], 0xffffffffu);
            atomicStore(&tile_max[i], 0u);
        }
        atomicStore(&tile_count, 0u);
        atomicStore(&tile_hidden, 0u);
    }
    workgroupBarrier();

    let inside = gid.x < view.size.x && gid.y < view.size.y;
    let point = trace_point(gid.xy, inside);
    var surface = point.depth > 0.0;
    var p = vec3<f32>(0.0);
    if surface {
        p = position_from_depth(point.screen, point.depth);
        // Beyond a directional light's max view distance, or beyond a point or spot
        // light's range or cone: not traced (lit). A tile with no traced pixel gathers
        // no caster at all.
        surface = traces_point(light, p);
    }
    let ray = shadow_ray(p, light);
    // The surface's normal: its G-buffer normal turned to face the eye, unless a caster's
    // field gives its own (below). Every surface pixel widens its tile's cone: the field
    // may face the light where the G-buffer normal does not.
    var normal = vec3<f32>(0.0);
    var horizon = 1.0;
    // Whether `normal` is the G-buffer's as stored, facing the eye (the side seen).
    var as_stored = false;
    var stored = vec3<f32>(0.0);
    // The pixel's triangle is known (the face-normal prepass): its plane, facing the eye
    // (`p` is camera-relative), alone gives the own shadow, as a ray tracer's does.
    let facet = surface && any(point.face != vec3<f32>(0.0));
    if facet {
        normal = select(point.face, -point.face, dot(point.face, p) > 0.0);
        as_stored = true;
        horizon = horizon_visibility(normal, ray.dir, ray.tan_half);
    } else if surface && (view.size.w & TRACE_GBUFFER_NORMALS) != 0u {
        stored = gbuffer_normal(point.normal_word);
        normal = facing_the_eye(stored, p);
        as_stored = all(normal == stored);
        horizon = horizon_visibility(normal, ray.dir, ray.tan_half);
        if horizon < 1.0 {
            atomicStore(&tile_hidden, 1u);
        }
    }
    if surface {
        for (var i = 0u; i < 3u; i += 1u) {
            atomicMin(&tile_min[i], order_key(p[i]));
            atomicMax(&tile_max[i], order_key(p[i]));
        }
    }
    workgroupBarrier();

    // The tile's round cone: from its bounding ball to the light's end ball.
    let lo = vec3<f32>(
        from_order_key(atomicLoad(&tile_min[0])),
        from_order_key(atomicLoad(&tile_min[1])),
        from_order_key(atomicLoad(&tile_min[2])),
    );
    let hi = vec3<f32>(
        from_order_key(atomicLoad(&tile_max[0])),
        from_order_key(atomicLoad(&tile_max[1])),
        from_order_key(atomicLoad(&tile_max[2])),
    );
    let any_surface = atomicLoad(&tile_min[0]) <= atomicLoad(&tile_max[0]);
    let tile_center = (lo + hi) * 0.5;
    let tile_radius = length(hi - lo) * 0.5;
    var cone_end: vec3<f32>;
    var cone_end_radius: f32;
    if is_directional(light) {
        // With the grid: no caster lies beyond the grid's height along the light, so
        // the tile's cone can stop there.
        var reach = light.max_distance;
        if grid_view.u.w > 0.5 && grid.height != 0u {
            let top = from_order_key(grid.height) - dot(tile_center, grid_light(grid_view)) + tile_radius;
            reach = clamp(top * (1.0 + 1e-4) + 1e-4, 0.0, light.max_distance);
        }
        cone_end = tile_center + light.position_or_direction.xyz * reach;
        cone_end_radius = tile_radius + reach * light.source;
    } else {
        // Every pixel's cone ends in a ball of radius < source around a point of the
        // light's sphere: inside the ball of twice the radius.
        cone_end = light.position_or_direction.xyz;
        cone_end_radius = 2.0 * light.source;
    }
    if li == 0u {
        tile_reads_fields = atomicLoad(&tile_hidden);
        tile_mode = 0u;
        total_n = light_object_count[0];
        if !any_surface {
            total_n = 0u;
        } else if is_directional(light) && grid_view.u.w > 0.5 {
            // The cells under the tile's shadow disc (its round cone seen along the
            // light); too many cells: the light's list is cheaper.
            var cells = vec4<i32>(1, 1, 0, 0);
            let glo = vec2<f32>(from_order_key(grid.bounds[0]), from_order_key(grid.bounds[1]));
            let ghi = vec2<f32>(from_order_key(grid.bounds[2]), from_order_key(grid.bounds[3]));
            if glo.x <= ghi.x {
                let center = vec2<f32>(dot(tile_center, grid_view.u.xyz), dot(tile_center, grid_view.v.xyz));
                cells = cell_range(grid_frame(glo, ghi), center, cone_end_radius + cull_slack(cone_end_radius));
            }
            if range_cells(cells) <= MAX_CELLS {
                tile_mode = 1u;
                tile_cells = cells;
                tile_large = grid.large_count;
                var n = grid.large_count;
                for (var y = cells.y; y <= cells.w; y += 1) {
                    for (var x = cells.x; x <= cells.z; x += 1) {
                        n += grid.counts[u32(y) * GRID_SIZE + u32(x)];
                    }
                }
                total_n = n;
            }
        }
    }
    let total = workgroupUniformLoad(&total_n);
    let mode = tile_mode;
    let cells = tile_cells;
    let large_n = tile_large;

    let tile = TileCone(tile_center, tile_radius, cone_end, cone_end_radius);

    // The surface's own shadow, from the normal of the caster field it lies on (the
    // triangles' facing, not a smooth or normal-mapped G-buffer normal), else from the
    // G-buffer's; where it hides the whole light, no march.
    var field = NO_FIELD_NORMAL;
    var field_slot = 0u;
    if workgroupUniformLoad(&tile_reads_fields) != 0u {
        var best = NO_FIELD_NORMAL;
        var best_slot = 0xffffffffu;
        for (var base = 0u; base < total; base += TILE_PIXELS) {
            let n = list_casters(base, li, total, mode, cells, large_n, tile);
            if surface && horizon < 1.0 && !facet {
                for (var i = 0u; i < n; i += 1u) {
                    let sphere = tile_spheres[i];
                    let v = p - sphere.xyz;
                    if sphere.w >= 0.0 && dot(v, v) <= sphere.w * sphere.w {
                        let slot = tile_slots[i];
                        let f = caster_field_normal(
                            objects[slot], p, normal, view.camera_tile.xyz, view.camera_offset.xyz, atlas, brick_table,
                        );
                        if f.w < best.w || (f.w == best.w && f.w < 3.0e38 && slot < best_slot) {
                            best = f;
                            best_slot = slot;
                        }
                    }
                }
            }
            workgroupBarrier();
        }
        field = best;
        field_slot = best_slot;
    }
    // Where the G-buffer normal hides the light and is not the face's own, the field's
    // normal decides: from facing 0 (its own horizon) on a caster shaded apart from its
    // faces, from FIELD_NORMAL_MIN_FACING (fully lit) on the others. The field must agree
    // with the G-buffer normal as turned to face the eye or as stored (a normal map's
    // normal past a grazing view's silhouette, which `facing_the_eye` negated).
    var neighbours: array<vec4<f32>, 4>;
    if surface && horizon < 1.0 && any(normal != vec3<f32>(0.0)) && !facet {
        neighbours = depth_neighbours(vec2<i32>(point.screen) + vec2<i32>(view.viewport.xy), point.screen, p);
    }
    let flat = flat_shaded(neighbours, normal);
    // Whether the field the receiver lies on is a caster's shaded apart from its faces.
    let field_apart = field.w < 3.0e38 && (objects[field_slot].flags & FLAG_SHADING_APART) != 0u;
    if surface && horizon < 1.0 && any(normal != vec3<f32>(0.0)) && field.w < 3.0e38
        && max(dot(field.xyz, normal), dot(field.xyz, stored)) >= FIELD_NORMAL_MIN_AGREEMENT
        && !flat && !facet {
        let facing = dot(field.xyz, ray.dir);
        if field_apart && facing >= FIELD_NORMAL_MIN_FACING_SHADED {
            normal = field.xyz;
            horizon = horizon_visibility(normal, ray.dir, ray.tan_half);
            as_stored = false;
        } else if facing >= FIELD_NORMAL_MIN_FACING {
            normal = field.xyz;
            horizon = 1.0;
            as_stored = false;
        }
    }
    // Still hidden and still the G-buffer's own normal (not a flat-shaded face's), on a
    // caster shaded apart from its faces or on no caster field: the depth buffer's face
    // normal, where it agrees, gives the triangles' facing (a smooth normal just past
    // the terminator of facets that face the light). Not on other casters: a scanned
    // mesh's pixel-sized facets make the depth buffer's plane no face's, and its
    // G-buffer normals are its faces'.
    if surface && horizon < 1.0 && as_stored && !flat && !facet
        && (field.w >= 3.0e38 || field_apart) {
        let face = depth_face_normal(neighbours, normal);
        if dot(face, normal) >= FACE_NORMAL_MIN_AGREEMENT {
            normal = face;
            horizon = horizon_visibility(normal, ray.dir, ray.tan_half);
            as_stored = false;
        }
    }
    let march = surface && horizon > 0.0;

    // A solid caster the receiver sees from its inside is not marched; its reversed
    // field normal shades the receiver instead (the least over such casters; 2: none).
    // Asked only with the G-buffer's normal as stored, facing the eye: not where
    // `facing_the_eye` turned it (a normal map's at a grazing view) nor where a field's
    // normal replaced it (the field's outside).
    var inside_horizon = 2.0;
    var visibility = 1.0;
    for (var base = 0u; base < total; base += TILE_PIXELS) {
        let n = list_casters(base, li, total, mode, cells, large_n, tile);
        if march {
            for (var i = 0u; i < n; i += 1u) {
                let sphere = tile_spheres[i];
                if object_in_cone(sphere, p, ray) {
                    let o = objects[tile_slots[i]];
                    // A receiver inside an analytic shape is not shadowed by it: the
                    // shape stands in for the receiver's own mesh (a character's capsules;
                    // `shadow_mask::inside_analytic`).
                    if inside_analytic(o, p, view.camera_tile.xyz, view.camera_offset.xyz, atlas, brick_table) {
                        continue;
                    }
                    if as_stored && seen_from_inside(o, sphere, p, normal, view.camera_tile.xyz, view.camera_offset.xyz, atlas, brick_table) {
                        // With the pixel's triangle known, its plane already gave the
                        // own shadow.
                        if !facet {
                            let f = caster_field_normal(o, p, normal, view.camera_tile.xyz, view.camera_offset.xyz, atlas, brick_table);
                            if f.w < 3.0e38 {
                                inside_horizon = min(inside_horizon, horizon_visibility(-f.xyz, ray.dir, ray.tan_half));
                            }
                        }
                        continue;
                    }
                    let v = march_object(
                        o, sphere, p, ray, light, march_start(o, normal, ray.dir, light.bias),
                        view.camera_tile.xyz, view.camera_offset.xyz, atlas, brick_table,
                    );
                    visibility = min(visibility, v);
                }
            }
        }
        workgroupBarrier();
    }
    if march {
        visibility = min(visibility, terrain_visibility(p, ray));
    }
    if inside_horizon <= 1.0 {
        horizon = inside_horizon;
    }
    if point.store {
        var out = 1.0;
        if surface {
            out = min(finish_visibility(visibility, light.shaping), horizon);
        }
        textureStore(mask, vec2<i32>(gid.xy), vec4<f32>(out, 0.0, 0.0, 1.0));
    }
}

// The tile's round cone: from its bounding ball to the light's end ball.
struct TileCone {
    center: vec3<f32>,
    radius: f32,
    end: vec3<f32>,
    end_radius: f32,
}

// Lists the casters `base .. base + TILE_PIXELS` of the tile's candidates (the light's
// list, or the grid cells under the tile's shadow disc: `mode`) that cast shadows and
// meet the tile's cone into `tile_slots` / `tile_spheres`, one per thread; returns how
// many (uniform). Call from uniform control flow, with a barrier before the next call.
fn list_casters(
    base: u32,
    li: u32,
    total: u32,
    mode: u32,
    cells: vec4<i32>,
    large_n: u32,
    tile: TileCone,
) -> u32 {
    let k = base + li;
    if k < total {
        var slot = 0u;
        var keep = true;
        if mode == 0u {
            slot = light_objects[k];
        } else if k < large_n {
            slot = grid_large[k];
        } else {
            // The k-th item of the tile's cells, row by row; a caster listed in
            // several of them is kept in the first only.
            var j = k - large_n;
            var cell = vec2<i32>(0);
            var found = false;
            for (var y = cells.y; y <= cells.w && !found; y += 1) {
                for (var x = cells.x; x <= cells.z && !found; x += 1) {
                    let c = u32(y) * GRID_SIZE + u32(x);
                    let n = grid.counts[c];
                    if j < n {
                        slot = grid_items[grid.offsets[c] + j];
                        cell = vec2<i32>(x, y);
                        found = true;
                    } else {
                        j -= n;
                    }
                }
            }
            let glo = vec2<f32>(from_order_key(grid.bounds[0]), from_order_key(grid.bounds[1]));
            let ghi = vec2<f32>(from_order_key(grid.bounds[2]), from_order_key(grid.bounds[3]));
            let disc = light_space_disc(objects[slot], grid_view);
            let own = cell_range(grid_frame(glo, ghi), disc.xy, disc.z);
            keep = found && all(cell == max(cells.xy, own.xy));
        }
        let o = objects[slot];
        let sphere = bounding_sphere(o, view.camera_tile.xyz, view.camera_offset.xyz);
        keep = keep && casts_shadows(o) && (sphere.w < 0.0
            || round_cone_distance(sphere.xyz, tile.center, tile.end, tile.radius, tile.end_radius)
                < sphere.w + cull_slack(sphere.w));
        if keep {
            let n = atomicAdd(&tile_count, 1u);
            tile_slots[n] = slot;
            tile_spheres[n] = sphere;
        }
    }
    workgroupBarrier();
    if li == 0u {
        tile_n = atomicLoad(&tile_count);
        atomicStore(&tile_count, 0u);
    }
    return workgroupUniformLoad(&tile_n);
}
