//! Distance-field shadows of many small lights: the mask pass's work (distance
//! evaluations per pixel, summed over the lights) and the model's run time, for a
//! 12 × 12 m floor with boxes and spheres under 8 small point lights (range 2.5 m) and
//! 2 spot lights (30°), seen from above at 128 × 128.
//!
//! A light lights nothing beyond its range (Bevy's attenuation reaches 0 there) nor
//! outside a spot's outer cone: the pass does not march such pixels. This bench
//! checks that this changes nothing where the light reaches (every such pixel's
//! visibility equals a full march's) and reports what it saves.
//!
//! `cargo bench -p penumbra_reference --bench df_shadow_lights`

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

use criterion::{Criterion, criterion_group};
use glam::{Affine3A, Mat4, UVec3, Vec2, Vec3};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode, flags};
use penumbra_df_core::shadow::{ShadowLight, ShadowLightKind};
use penumbra_reference::df::{Atlas, DebugScene};
use penumbra_reference::shadow_mask::pixel_visibility_counted;

const SIZE: u32 = 128;

struct Frame {
    records: Vec<ObjectRecord>,
    atlas: Atlas,
    camera: CameraOrigin,
    /// Camera-relative surface point and unit normal per pixel (`None`: background).
    pixels: Vec<Option<(Vec3, Vec3)>>,
    lights: Vec<ShadowLight>,
}

fn frame() -> Frame {
    let live = flags::LIVE | flags::CASTS_SHADOWS | flags::VISIBLE;
    let mut casters = vec![(CasterShape::Plane, Affine3A::IDENTITY)];
    for i in 0..6 {
        let x = -5.0 + 2.0 * i as f32;
        casters.push((
            CasterShape::Cuboid {
                half_extents: Vec3::new(0.3, 0.4, 0.3),
            },
            Affine3A::from_translation(Vec3::new(x, 0.4, -2.0 + (i % 3) as f32)),
        ));
        casters.push((
            CasterShape::Sphere { radius: 0.35 },
            Affine3A::from_translation(Vec3::new(x + 1.0, 0.35, 2.0 - (i % 2) as f32)),
        ));
    }
    let records: Vec<ObjectRecord> = casters
        .into_iter()
        .map(|(shape, world_from_local)| {
            encode(&ObjectDesc {
                world_from_local,
                shape,
                flags: live,
            })
            .expect("encodes")
        })
        .collect();
    let atlas = Atlas::new(UVec3::splat(2));
    let eye = Vec3::new(0.0, 9.0, 8.0);
    let camera = CameraOrigin::at(eye).expect("finite");
    let view = Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
    let proj = Mat4::perspective_infinite_reverse_rh(0.9, 1.0, 0.1);
    let clip_from_relative = proj * Mat4::from_mat3(glam::Mat3::from_mat4(view));
    let scene = DebugScene {
        objects: records.iter().collect(),
        atlas: &atlas,
        camera,
        relative_from_clip: clip_from_relative.inverse(),
        max_steps: 256,
        max_distance: 60.0,
    };
    let pixels = (0..SIZE * SIZE)
        .map(|i| {
            let uv = (Vec2::new((i % SIZE) as f32, (i / SIZE) as f32) + 0.5) / SIZE as f32;
            let dir = scene.ray(uv);
            let (t, _, hit) = scene.trace(dir);
            hit.then(|| {
                let p = dir * t;
                let e = 1e-3;
                let g = |a: Vec3| scene.distance(p + a * e) - scene.distance(p - a * e);
                (p, Vec3::new(g(Vec3::X), g(Vec3::Y), g(Vec3::Z)).normalize())
            })
        })
        .collect();
    let positional = |at: Vec3, spot: Option<(Vec3, f32)>| ShadowLight {
        kind: ShadowLightKind::Positional(camera.relative([0, 0, 0], at)),
        source: 0.05,
        max_distance: 0.0,
        bias: 0.04,
        shaping: 1.25,
        range: 2.5,
        max_steps: 64,
        max_view_distance: 150.0,
        spot,
    };
    let mut lights: Vec<ShadowLight> = (0..8)
        .map(|i| {
            let at = Vec3::new(
                -4.5 + 3.0 * (i % 4) as f32,
                1.2,
                -1.5 + 3.0 * (i / 4) as f32,
            );
            positional(at, None)
        })
        .collect();
    for x in [-3.0, 3.0] {
        let down = Vec3::new(0.2, -1.0, 0.1).normalize();
        lights.push(positional(
            Vec3::new(x, 2.0, 0.0),
            Some((down, 30f32.to_radians().cos())),
        ));
    }
    Frame {
        records,
        atlas,
        camera,
        pixels,
        lights,
    }
}

/// Per light: (the mask, distance evaluations, pixels marched at all).
fn masks(f: &Frame) -> Vec<(Vec<f32>, u64, usize)> {
    f.lights
        .iter()
        .map(|light| {
            let (mut evaluations, mut marched) = (0u64, 0usize);
            let mask = f
                .pixels
                .iter()
                .map(|px| match px {
                    Some((p, n)) => {
                        let (v, e) = pixel_visibility_counted(
                            &f.records, &f.atlas, &f.camera, *p, *n, light,
                        );
                        evaluations += e as u64;
                        marched += usize::from(e > 0);
                        v
                    }
                    None => 1.0,
                })
                .collect();
            (mask, evaluations, marched)
        })
        .collect()
}

/// Whether the light reaches camera-relative `p` (Bevy's range and spot attenuation).
fn reaches(light: &ShadowLight, p: Vec3) -> bool {
    let ShadowLightKind::Positional(at) = light.kind else {
        return true;
    };
    let v = p - at;
    let inside_cone = light
        .spot
        .is_none_or(|(dir, cos_outer)| v.normalize().dot(dir) > cos_outer);
    v.length() < light.range && inside_cone
}

fn bench(c: &mut Criterion) {
    let f = frame();
    let surface = f.pixels.iter().filter(|p| p.is_some()).count();
    let results = masks(&f);
    // Point lights first, then spots.
    let points = f.lights.iter().filter(|l| l.spot.is_none()).count();
    for (name, range) in [
        ("8 point lights", 0..points),
        ("2 spot lights", points..f.lights.len()),
    ] {
        let part = &results[range];
        let total: u64 = part.iter().map(|r| r.1).sum();
        let marched: usize = part.iter().map(|r| r.2).sum();
        println!(
            "{name}, {SIZE}×{SIZE} view ({surface} surface pixels): {:.2} distance evaluations \
             per pixel (all of them together), {:.1} % of pixel-light pairs marched",
            total as f64 / (SIZE * SIZE) as f64,
            100.0 * marched as f64 / (surface * part.len()) as f64
        );
    }
    // Where the light reaches, the early-out must change nothing: compare with a full
    // march (the light with infinite range and no cone: the same visibility there).
    let mut worst = 0.0f32;
    for (light, (mask, ..)) in f.lights.iter().zip(&results) {
        let unbounded = ShadowLight {
            range: f32::INFINITY,
            spot: None,
            ..*light
        };
        for (px, v) in f.pixels.iter().zip(mask) {
            if let Some((p, n)) = px
                && reaches(light, *p)
            {
                let (full, _) =
                    pixel_visibility_counted(&f.records, &f.atlas, &f.camera, *p, *n, &unbounded);
                worst = worst.max((full - v).abs());
            }
        }
    }
    println!("max |Δ| against a full march where the light reaches: {worst:.5}");
    c.bench_function("df_shadow_lights/8 point + 2 spot lights", |b| {
        b.iter(|| masks(&f));
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}

fn main() {
    benches();
    Criterion::default().final_summary();
}
