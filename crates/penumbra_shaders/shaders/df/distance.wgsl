// Distances to distance-field objects: the shared evaluation every distance-field pass
// uses. CPU reference: `penumbra_reference::df::object_distance`.
#define_import_path penumbra::df::distance

#import penumbra::df::object::{
    DistanceFieldObject, FLAG_BRICKED, KIND_CAPSULE, KIND_CUBOID, KIND_PLANE, KIND_SPHERE,
    KIND_VOLUME, TILE_SIZE, object_kind, transform_rows, unpack_10_10_12,
}

// The brick table (`penumbra_df_core::bricks`): texels per row, the empty-brick tag.
const BRICK_TABLE_WIDTH: u32 = 4096u;
const BRICK_EMPTY: u32 = 0x80000000u;
// Samples along a brick's edge (one atlas block); bricks overlap by one sample.
const BRICK_SAMPLES: u32 = 8u;
// Table entries before a volume's bricks (its coarse grid's atlas origin).
const BRICK_HEADER_ENTRIES: u32 = 1u;
// Voxels an empty brick's coarse distance moves toward zero.
const BRICK_COARSE_SLACK: f32 = 1.0;

// Trilinear sample of a volume at voxel coordinates `c` (inside [0, dims − 1]), read
// with exact texel loads (no filtering hardware: the same arithmetic on every device
// and on the CPU).
fn sample_volume(atlas: texture_3d<f32>, origin: vec3<u32>, dims: vec3<u32>, c: vec3<f32>) -> f32 {
    let hi = vec3<f32>(dims - vec3<u32>(1u));
    let i0 = min(floor(c), hi - vec3<f32>(1.0));
    let f = c - i0;
    let base = vec3<i32>(origin) + vec3<i32>(i0);
    let c000 = textureLoad(atlas, base, 0).r;
    let c100 = textureLoad(atlas, base + vec3<i32>(1, 0, 0), 0).r;
    let c010 = textureLoad(atlas, base + vec3<i32>(0, 1, 0), 0).r;
    let c110 = textureLoad(atlas, base + vec3<i32>(1, 1, 0), 0).r;
    let c001 = textureLoad(atlas, base + vec3<i32>(0, 0, 1), 0).r;
    let c101 = textureLoad(atlas, base + vec3<i32>(1, 0, 1), 0).r;
    let c011 = textureLoad(atlas, base + vec3<i32>(0, 1, 1), 0).r;
    let c111 = textureLoad(atlas, base + vec3<i32>(1, 1, 1), 0).r;
    let x00 = c000 + (c100 - c000) * f.x;
    let x10 = c010 + (c110 - c010) * f.x;
    let x01 = c001 + (c101 - c001) * f.x;
    let x11 = c011 + (c111 - c011) * f.x;
    let y0 = x00 + (x10 - x00) * f.y;
    let y1 = x01 + (x11 - x01) * f.y;
    return y0 + (y1 - y0) * f.z;
}

// An empty brick's distance from its nearest sample `least` and the coarse grid's
// `coarse` (`penumbra_sdf::bricks::empty_distance`).
fn empty_brick_distance(least: f32, coarse: f32) -> f32 {
    if least >= 0.0 {
        return max(least, coarse - BRICK_COARSE_SLACK);
    }
    return min(least, coarse + BRICK_COARSE_SLACK);
}

fn brick_table_entry(brick_table: texture_2d<u32>, index: u32) -> u32 {
    return textureLoad(brick_table, vec2<u32>(index % BRICK_TABLE_WIDTH, index / BRICK_TABLE_WIDTH), 0).r;
}

// A bricked volume's field at grid coordinates `c` (inside [0, dims − 1]), its table
// entries from `table_offset` (a header: its coarse grid's atlas origin; then one per
// brick): the trilinear sample of its brick in the atlas, or an empty brick's distance
// from its nearest sample and the coarse grid (`penumbra_sdf::bricks`). CPU reference:
// `penumbra_reference::df::sample_bricked`.
fn sample_bricked(
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
    table_offset: u32,
    dims: vec3<u32>,
    c: vec3<f32>,
) -> f32 {
    let span = BRICK_SAMPLES - 1u;
    let grid = (dims - vec3<u32>(1u) + vec3<u32>(span - 1u)) / span;
    let b = min(vec3<u32>(max(floor(c / f32(span)), vec3<f32>(0.0))), grid - vec3<u32>(1u));
    let local = c - vec3<f32>(b * span);
    let index = table_offset + BRICK_HEADER_ENTRIES + b.x + grid.x * (b.y + grid.y * b.z);
    let entry = brick_table_entry(brick_table, index);
    if (entry & BRICK_EMPTY) != 0u {
        // The brick's far corners are the grid's last samples where it overhangs.
        let coarse_origin = unpack_10_10_12(brick_table_entry(brick_table, table_offset));
        let width = min(dims - vec3<u32>(1u) - b * span, vec3<u32>(span));
        let at = vec3<f32>(b) + local / vec3<f32>(width);
        let coarse = sample_volume(atlas, coarse_origin, grid + vec3<u32>(1u), at);
        return empty_brick_distance(unpack2x16float(entry & 0xffffu).x, coarse);
    }
    let block = vec3<u32>(entry & 0x7fu, (entry >> 7u) & 0x7fu, (entry >> 14u) & 0x1ffu);
    return sample_volume(atlas, block * BRICK_SAMPLES, vec3<u32>(BRICK_SAMPLES), local);
}

// A volume's trilinear field at grid coordinates `c` (inside [0, dims − 1]): dense from
// the atlas at `first`, or bricked with its table entries from `first`.
fn volume_field(
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
    bricked: bool,
    first: u32,
    dims: vec3<u32>,
    c: vec3<f32>,
) -> f32 {
    if bricked {
        return sample_bricked(atlas, brick_table, first, dims, c);
    }
    return sample_volume(atlas, unpack_10_10_12(first), dims, c);
}

// The distance (voxels) at grid coordinates `q` of a volume whose surface lies at least
// `margin` voxels inside its box: trilinear inside the box; outside, ±√(e² + s²) with `e`
// the distance to the box shrunk by the margin and `s` the sample at its nearest point —
// a lower bound of the true distance, since every surface point lies in that (convex)
// box: |q − x|² ≥ e² + |c − x|². (The clamped sample plus the distance to the box,
// Unreal's, is an upper bound and lets a step jump past a surface lying obliquely inside
// the border.) Negative only where the box's own boundary sample is too (a ground
// sheet's solid goes on below its box). CPU reference:
// `penumbra_sdf::volume::volume_distance_voxels`.
fn volume_distance(
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
    bricked: bool,
    first: u32,
    dims: vec3<u32>,
    margin: f32,
    q: vec3<f32>,
) -> f32 {
    let hi = vec3<f32>(dims - vec3<u32>(1u));
    if all(q >= vec3<f32>(0.0)) && all(q <= hi) {
        return volume_field(atlas, brick_table, bricked, first, dims, q);
    }
    // NaN margins fall back to 0; the shrunk box stays non-empty.
    var m = clamp(margin, 0.0, 0.5 * min(hi.x, min(hi.y, hi.z)));
    m = select(0.0, m, m >= 0.0);
    let c = clamp(q, vec3<f32>(m), hi - vec3<f32>(m));
    let s = volume_field(atlas, brick_table, bricked, first, dims, c);
    let e = q - c;
    let r = sqrt(dot(e, e) + s * s);
    // Inside only where the inside reaches the box's own boundary (a ground sheet's
    // solid): the shrunk box's sample may read inside a voxel beyond the mesh (the
    // thin-feature guard) while the box's boundary is outside.
    if s < 0.0 && volume_field(atlas, brick_table, bricked, first, dims, clamp(q, vec3<f32>(0.0), hi)) < 0.0 {
        return -r;
    }
    return r;
}

// Conservative world distance (metres) from camera-relative point `p` to `o`. Volumes'
// texels hold distances in voxels (`conservative_scale` is per voxel for them; `f.z` is
// their margin; with FLAG_BRICKED, `params.x` is their first brick-table entry).
fn object_distance(
    o: DistanceFieldObject,
    p: vec3<f32>,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> f32 {
    let p_tile = vec3<f32>(camera_tile - o.tile) * TILE_SIZE + (p + camera_offset);
    let q = transform_rows(o.shape_from_world, p_tile);
    let f = bitcast<vec3<f32>>(o.params);
    var d = 0.0;
    switch object_kind(o) {
        case KIND_VOLUME: {
            let dims = unpack_10_10_12(o.params.y) + vec3<u32>(1u);
            let bricked = (o.flags & FLAG_BRICKED) != 0u;
            d = volume_distance(atlas, brick_table, bricked, o.params.x, dims, f.z, q);
        }
        case KIND_SPHERE: {
            d = length(q) - f.x;
        }
        case KIND_CUBOID: {
            let a = abs(q) - f;
            d = length(max(a, vec3<f32>(0.0))) + min(max(a.x, max(a.y, a.z)), 0.0);
        }
        case KIND_CAPSULE: {
            let y = clamp(q.y, -f.y, f.y);
            d = length(q - vec3<f32>(0.0, y, 0.0)) - f.x;
        }
        case KIND_PLANE: {
            d = q.y;
        }
        default: {
            d = 1e30;
        }
    }
    return d * o.conservative_scale;
}
