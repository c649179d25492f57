//! A volume stored as sparse bricks (`penumbra_sdf::bricks`, addressed through the brick
//! table of `penumbra_df_core::bricks`) reads as its dense twin near the surface and as
//! a conservative bound elsewhere, in the passes' model (`df::object_distance`), and is
//! as close to the triangles' exact distance (brute force, f64) as the dense field.

use glam::{Affine3A, DVec3, Quat, UVec3, Vec3};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode, flags};
use penumbra_reference::df::{Atlas, object_distance};
use penumbra_sdf::bricks::{BrickedVolume, DEFAULT_BAND_VOXELS};
use penumbra_sdf::{BakeSettings, bake, exact, shapes};

fn record(shape: CasterShape, world: Affine3A) -> ObjectRecord {
    encode(&ObjectDesc {
        world_from_local: world,
        shape,
        flags: flags::VISIBLE | flags::CASTS_SHADOWS,
    })
    .expect("encodes")
}

/// Points of the box `[lo, hi]` grown by `grow` (a 3-D Halton set).
fn points(lo: DVec3, hi: DVec3, grow: f64, n: u32) -> impl Iterator<Item = DVec3> {
    let (lo, hi) = (lo - grow, hi + grow);
    (1..=n).map(move |i| lo + (hi - lo) * DVec3::from(penumbra_testkit::halton3(i)))
}

#[test]
fn the_brick_layouts_agree() {
    assert_eq!(
        penumbra_sdf::bricks::BRICK_SAMPLES,
        penumbra_df_core::bricks::BRICK_SAMPLES
    );
}

#[test]
fn a_bricked_volume_reads_as_its_dense_twin_near_the_surface_and_below_it_elsewhere() {
    let mesh = shapes::torus(0.6, 0.15, 48, 24);
    let v = bake(&mesh, &BakeSettings::longest_axis(72), None)
        .expect("bakes")
        .volume;
    let bricked = BrickedVolume::from_volume(&v, DEFAULT_BAND_VOXELS);
    let share = bricked.bytes() as f64 / bricked.dense_bytes() as f64;
    println!(
        "{} of {} bricks stored: {} bytes, {share:.3} of dense",
        bricked.stored(),
        bricked.bricks.len(),
        bricked.bytes()
    );
    // A thin torus on a small grid: most bricks are near the surface (bricks pay on
    // large grids; `penumbra_sdf::bricks` tests the share).
    assert!(bricked.stored() < bricked.bricks.len());

    let mut atlas = Atlas::new(UVec3::new(80, 80, 136));
    let region = AtlasRegion {
        origin: UVec3::ZERO,
        dims: v.dims,
    };
    let bits: Vec<u16> = v.data.iter().map(|h| h.to_bits()).collect();
    atlas.write(region.origin, region.dims, &bits);
    atlas.table.extend([0xdead_beef; 5]); // another volume's entries first
    let table_offset = atlas
        .place_bricked(&bricked, UVec3::new(0, 0, 80), UVec3::new(64, 0, 80))
        .expect("the pool fits");
    assert_eq!(table_offset, 5);

    let world = Affine3A::from_scale_rotation_translation(
        Vec3::new(1.5, 1.5, 1.5),
        Quat::from_rotation_y(0.8) * Quat::from_rotation_x(0.3),
        Vec3::new(2.0, 1.0, -3.0),
    );
    let (local_origin, voxel_size, margin) = (v.origin.as_vec3(), v.voxel_size, v.margin);
    let dense = record(
        CasterShape::Volume {
            region,
            local_origin,
            voxel_size,
            margin,
        },
        world,
    );
    let sparse = record(
        CasterShape::BrickedVolume {
            table_offset,
            dims: v.dims,
            local_origin,
            voxel_size,
            margin,
        },
        world,
    );
    assert_ne!(sparse.flags() & flags::BRICKED, 0);
    assert_eq!(dense.flags() & flags::BRICKED, 0);

    let (tris, _) = mesh.validate().expect("valid");
    let world_tris: Vec<[DVec3; 3]> = tris
        .iter()
        .map(|t| t.map(|p| world.transform_point3(p).as_dvec3()))
        .collect();
    let camera = CameraOrigin::at(Vec3::new(1.0, 2.0, 0.0)).expect("camera");
    let voxel = 1.5 * voxel_size as f64;
    let (lo, hi) = v.bounds();
    let (mut near, mut far) = (0, 0);
    let (mut worst_twin, mut worst_dense, mut worst_sparse) = (0.0f64, 0.0f64, 0.0f64);
    for local in points(lo, hi, 4.0 * voxel_size as f64, 6000) {
        let p_world = world.transform_point3(local.as_vec3());
        let p = p_world - Vec3::new(1.0, 2.0, 0.0);
        let d = object_distance(&dense, p, &camera, &atlas) as f64;
        let s = object_distance(&sparse, p, &camera, &atlas) as f64;
        assert!(
            d.signum() == s.signum() && s.abs() <= d.abs() + 1e-5,
            "{local}: bricked {s}, dense {d}"
        );
        // Inside the box the model reads what `BrickedVolume` says.
        let g = ((local - v.origin) / voxel_size as f64).as_vec3();
        if g.cmpge(Vec3::ZERO).all() && g.cmple((v.dims - UVec3::ONE).as_vec3()).all() {
            let want = bricked.sample_voxels(g) as f64 * voxel;
            assert!(
                (s - want).abs() < 1e-5,
                "{local}: model {s}, BrickedVolume {want}"
            );
        }
        if d.abs() < (DEFAULT_BAND_VOXELS as f64 - 1.0) * voxel {
            near += 1;
            worst_twin = worst_twin.max((s - d).abs());
            let truth = exact::distance(p_world.as_dvec3(), &world_tris);
            let truth = if d < 0.0 { -truth } else { truth };
            worst_dense = worst_dense.max((d - truth).abs() / voxel);
            worst_sparse = worst_sparse.max((s - truth).abs() / voxel);
        } else {
            far += 1;
        }
    }
    println!(
        "{near} points near the surface: bricked − dense ≤ {worst_twin:.2e} m; \
         against the triangles dense {worst_dense:.3}, bricked {worst_sparse:.3} voxel; {far} far"
    );
    assert!(near > 400 && far > 2000, "near {near}, far {far}");
    assert!(
        worst_twin < 1e-5,
        "bricked differs from dense by {worst_twin} m"
    );
    // Trilinear sampling of a 7-voxel-thick torus: within a voxel, as the dense field.
    assert!(
        worst_sparse <= worst_dense + 1e-9 && worst_sparse < 1.0,
        "bricked is {worst_sparse} voxel from the triangles (dense {worst_dense})"
    );
}
