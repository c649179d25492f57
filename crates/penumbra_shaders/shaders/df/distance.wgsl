// Distances to distance-field objects: the shared evaluation every distance-field pass
// uses. CPU reference: `penumbra_reference::df::object_distance`.
#define_import_path penumbra::df::distance

#import penumbra::df::object::{
    DistanceFieldObject, KIND_CAPSULE, KIND_CUBOID, KIND_PLANE, KIND_SPHERE, KIND_VOLUME,
    TILE_SIZE, object_kind, transform_rows, unpack_10_10_12,
}

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
    origin: vec3<u32>,
    dims: vec3<u32>,
    margin: f32,
    q: vec3<f32>,
) -> f32 {
    let hi = vec3<f32>(dims - vec3<u32>(1u));
    if all(q >= vec3<f32>(0.0)) && all(q <= hi) {
        return sample_volume(atlas, origin, dims, q);
    }
    // NaN margins fall back to 0; the shrunk box stays non-empty.
    var m = clamp(margin, 0.0, 0.5 * min(hi.x, min(hi.y, hi.z)));
    m = select(0.0, m, m >= 0.0);
    let c = clamp(q, vec3<f32>(m), hi - vec3<f32>(m));
    let s = sample_volume(atlas, origin, dims, c);
    let e = q - c;
    let r = sqrt(dot(e, e) + s * s);
    // Inside only where the inside reaches the box's own boundary (a ground sheet's
    // solid): the shrunk box's sample may read inside a voxel beyond the mesh (the
    // thin-feature guard) while the box's boundary is outside.
    if s < 0.0 && sample_volume(atlas, origin, dims, clamp(q, vec3<f32>(0.0), hi)) < 0.0 {
        return -r;
    }
    return r;
}

// Conservative world distance (metres) from camera-relative point `p` to `o`. Volumes'
// texels hold distances in voxels (`conservative_scale` is per voxel for them; `f.z` is
// their margin).
fn object_distance(
    o: DistanceFieldObject,
    p: vec3<f32>,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
) -> f32 {
    let p_tile = vec3<f32>(camera_tile - o.tile) * TILE_SIZE + (p + camera_offset);
    let q = transform_rows(o.shape_from_world, p_tile);
    let f = bitcast<vec3<f32>>(o.params);
    var d = 0.0;
    switch object_kind(o) {
        case KIND_VOLUME: {
            let dims = unpack_10_10_12(o.params.y) + vec3<u32>(1u);
            d = volume_distance(atlas, unpack_10_10_12(o.params.x), dims, f.z, q);
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
