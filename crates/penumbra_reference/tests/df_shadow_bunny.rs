//! The distance-field shadow march on a real mesh: the Stanford bunny's baked SDF
//! against Monte Carlo ground truth traced on its 69k triangles, for a soft sun over a
//! grid of ground points around it. Prints the mean and max error (the figure the
//! distance-field shadows' defaults will be judged by); asserts the march stays close.

use glam::Vec3;
use penumbra_reference::df_shadow::{
    AreaLight, Occluder, ShadowSettings, TriangleOccluder, df_visibility, monte_carlo_visibility,
};
use penumbra_sdf::{BakeSettings, SdfVolume, bake, obj};

/// The bunny's SDF, for the march.
struct SdfOccluder {
    volume: SdfVolume,
    center: Vec3,
    radius: f32,
}

impl Occluder for SdfOccluder {
    fn distance(&self, p: Vec3) -> f32 {
        self.volume.sample(p.as_dvec3())
    }
    fn blocks(&self, _: Vec3, _: Vec3, _: f32) -> bool {
        unreachable!("the march does not cast rays")
    }
    fn bounding_radius(&self) -> f32 {
        self.radius
    }
    fn center(&self) -> Vec3 {
        self.center
    }
}

#[test]
fn bunny_shadow_march_against_ray_traced_ground_truth() {
    let Some(dir) = penumbra_testkit::shared_dir(
        "bunny_shadow_march_against_ray_traced_ground_truth",
        env!("CARGO_MANIFEST_DIR"),
        "meshes",
    ) else {
        return;
    };
    let text = std::fs::read_to_string(dir.join("stanford-bunny.obj")).expect("the bunny");
    let mut mesh = obj::parse_obj(&text).unwrap();
    mesh.origin = glam::DVec3::ZERO; // work in the file's centred frame
    // Stand the bunny on y = 0.
    let min_y = mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    for p in &mut mesh.positions {
        p.y -= min_y;
    }
    let (tris, _) = mesh.validate().unwrap();
    let (lo, hi) = tris.iter().flatten().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(l, h), &p| (l.min(p), h.max(p)),
    );
    let (center, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let sdf = SdfOccluder {
        volume: bake(&mesh, &BakeSettings::longest_axis(64), None)
            .unwrap()
            .volume,
        center,
        radius,
    };
    let truth = TriangleOccluder::new(&tris);
    let light = AreaLight::Directional {
        to_light: Vec3::new(0.6, 0.75, 0.3).normalize(),
        angular_diameter: 3f32.to_radians(),
    };
    let settings = ShadowSettings {
        max_distance: 2.0,
        max_steps: 64,
        bias: 0.002,
    };
    let (mut sum, mut worst, mut shadowed, mut n) = (0.0f32, 0.0f32, 0, 0);
    // Over the points that either side puts in shadow or penumbra.
    let (mut sum_affected, mut affected) = (0.0f32, 0);
    let extent = hi - lo;
    for i in 0..24 {
        for k in 0..24 {
            let p = Vec3::new(
                lo.x - extent.x + 3.0 * extent.x * i as f32 / 23.0,
                0.0005,
                lo.z - extent.z + 3.0 * extent.z * k as f32 / 23.0,
            );
            if sdf.volume.sample(p.as_dvec3()) < 0.002 {
                continue; // under the bunny's feet
            }
            let march = df_visibility(&[&sdf], p, &light, &settings);
            let want = monte_carlo_visibility(&[&truth], p, Vec3::ZERO, &light, &settings, 16);
            sum += (march - want).abs();
            worst = worst.max((march - want).abs());
            shadowed += usize::from(want < 0.99);
            if want < 0.99 || march < 0.99 {
                sum_affected += (march - want).abs();
                affected += 1;
            }
            n += 1;
        }
    }
    let mean = sum / n as f32;
    let mean_affected = sum_affected / affected as f32;
    println!(
        "bunny on a plane, 3° sun: {n} ground points ({shadowed} in shadow or penumbra): \
         mean |march − truth| {mean:.4} overall, {mean_affected:.4} over the {affected} \
         shadowed by either, max {worst:.4}"
    );
    assert!(shadowed > 20, "the bunny casts a shadow on the grid");
    // Measured 0.0147 (0.040 with the one-sided penumbra, whose march that
    // underestimated distances by 3× gave 0.139).
    assert!(
        mean_affected < 0.03,
        "mean over shadowed points {mean_affected}"
    );
}
