// One distance-field caster instance: the GPU view of `penumbra_df_core::object`
// (128 bytes; the Rust encoder and this layout are checked against each other by
// `crates/penumbra_shaders/tests/layout.rs`).
#define_import_path penumbra::df::object

const TILE_SIZE: f32 = 512.0;

const FLAG_CASTS_SHADOWS: u32 = 1u;
const FLAG_CASTS_OCCLUSION: u32 = 2u;
const FLAG_TWO_SIDED: u32 = 4u;
const FLAG_VISIBLE: u32 = 8u;
const FLAG_UNBOUNDED: u32 = 16u;
const FLAG_LIVE: u32 = 32u;
const FLAG_CAST_HIDDEN_SHADOW: u32 = 64u;
const FLAG_SHADING_APART: u32 = 128u;
const FLAG_BRICKED: u32 = 4096u;
const KIND_SHIFT: u32 = 8u;
const KIND_MASK: u32 = 15u;
const AO_TRANSMISSION_SHIFT: u32 = 16u;
const AO_TRANSMISSION_MASK: u32 = 255u;

const KIND_VOLUME: u32 = 0u;
const KIND_SPHERE: u32 = 1u;
const KIND_CUBOID: u32 = 2u;
const KIND_CAPSULE: u32 = 3u;
const KIND_PLANE: u32 = 4u;

struct DistanceFieldObject {
    // Rows of the 3×4 matrix taking tile-relative world positions to shape space.
    shape_from_world: array<vec4<f32>, 3>,
    // Rows of the 3×4 matrix taking shape space to tile-relative world positions.
    world_from_shape: array<vec4<f32>, 3>,
    // World position = tile × TILE_SIZE + tile-relative position.
    tile: vec3<i32>,
    flags: u32,
    // Per kind: volume (atlas origin 10/10/12 — with FLAG_BRICKED, its first brick-table
    // entry — dims − 1 10/10/12, margin bits),
    // sphere (radius), cuboid (half extents), capsule (radius, half length).
    params: vec3<u32>,
    // World metres per shape-space distance unit (smallest singular value).
    conservative_scale: f32,
}

// An axis-aligned box in shape space; `bounded` is false for planes.
struct ShapeBounds {
    min: vec3<f32>,
    max: vec3<f32>,
    bounded: bool,
}

fn object_kind(o: DistanceFieldObject) -> u32 {
    return (o.flags >> KIND_SHIFT) & KIND_MASK;
}

// The share of a cone's light the object lets through where it would close the cone
// (`flags::ao_transmission`).
fn ao_transmission(o: DistanceFieldObject) -> f32 {
    return f32((o.flags >> AO_TRANSMISSION_SHIFT) & AO_TRANSMISSION_MASK) / 255.0;
}

fn unpack_10_10_12(p: u32) -> vec3<u32> {
    return vec3<u32>(p & 0x3ffu, (p >> 10u) & 0x3ffu, p >> 20u);
}

fn transform_rows(rows: array<vec4<f32>, 3>, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        dot(rows[0].xyz, p) + rows[0].w,
        dot(rows[1].xyz, p) + rows[1].w,
        dot(rows[2].xyz, p) + rows[2].w,
    );
}

// Column `i` of the linear part of a row-stored 3×4 matrix.
fn rows_column(rows: array<vec4<f32>, 3>, i: u32) -> vec3<f32> {
    return vec3<f32>(rows[0][i], rows[1][i], rows[2][i]);
}

fn shape_bounds(o: DistanceFieldObject) -> ShapeBounds {
    var b = ShapeBounds(vec3<f32>(0.0), vec3<f32>(0.0), false);
    if (o.flags & FLAG_UNBOUNDED) != 0u {
        return b;
    }
    let f = bitcast<vec3<f32>>(o.params);
    switch object_kind(o) {
        case KIND_VOLUME: {
            b = ShapeBounds(vec3<f32>(0.0), vec3<f32>(unpack_10_10_12(o.params.y)), true);
        }
        case KIND_SPHERE: {
            b = ShapeBounds(vec3<f32>(-f.x), vec3<f32>(f.x), true);
        }
        case KIND_CUBOID: {
            b = ShapeBounds(-f, f, true);
        }
        case KIND_CAPSULE: {
            let h = vec3<f32>(f.x, f.y + f.x, f.x);
            b = ShapeBounds(-h, h, true);
        }
        default: {}
    }
    return b;
}

// A tile-relative position `p` in `tile`, relative to a camera at `camera_offset` in
// `camera_tile`: small numbers wherever the scene is.
fn camera_relative(tile: vec3<i32>, p: vec3<f32>, camera_tile: vec3<i32>, camera_offset: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(tile - camera_tile) * TILE_SIZE + (p - camera_offset);
}
