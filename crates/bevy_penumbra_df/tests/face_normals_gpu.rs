//! Contract test of the shadow mask pass with the face-normal prepass bound
//! (`df/shadow_trace.wgsl`'s `pixel_face_normal`, `penumbra_df_core::shadow::
//! TRACE_FACE_NORMALS`): on the contract scene of `shadow_mask_gpu.rs`, with a triangle
//! normal per pixel that parts from its G-buffer normal, the GPU's mask equals the CPU
//! model's (`ReceiverNormal::facet`), and the triangle alone gives each pixel's own
//! shadow, as a ray tracer's does.

use glam::{Quat, Vec3};
use penumbra_reference::shadow_mask::{facing_the_eye, horizon, light_reaches, shadow_ray};
use penumbra_test::{GpuCompute, gpu_or_skip};

#[path = "support/shadow_passes.rs"]
mod support;

use support::*;

/// A 32-bit integer hash (lowbias32).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Per pixel of `view`: its G-buffer normal turned up to 50° about an axis of its
/// tangent plane (a facet of a smooth or normal-mapped surface), by its winding; every
/// fifth pixel's winding reversed (a double-sided back face seen), every seventh none
/// (a mesh the prepass does not draw).
fn facets(view: &View) -> Vec<Vec3> {
    (0..view.depth.len())
        .map(|i| {
            let h = hash(i as u32);
            if view.depth[i] <= 0.0 || i % 7 == 3 {
                return Vec3::ZERO;
            }
            let n = view.normal(i);
            let (u, _) = n.any_orthonormal_pair();
            let around =
                Quat::from_axis_angle(n, (h & 0xffff) as f32 / 65536.0 * std::f32::consts::TAU);
            let tilt = (h >> 16) as f32 / 65536.0 * 50f32.to_radians();
            let f = Quat::from_axis_angle(around * u, tilt) * n;
            if i % 5 == 1 { -f } else { f }
        })
        .collect()
}

#[test]
fn the_mask_takes_each_pixels_own_shadow_from_its_triangle() {
    if !gpu_or_skip("the_mask_takes_each_pixels_own_shadow_from_its_triangle") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let passes = passes(&gpu);
    // The torus read as a solid too: back faces seen on it ask `seen_from_inside`.
    // The sun and the sphere light; on the solid, the sun.
    for (name, scene, lights_run) in [
        ("shell", scene(Vec3::ZERO), 2),
        (
            "solid",
            scene_with_torus_flags(0, penumbra_df_core::object::flags::TWO_SIDED),
            1,
        ),
    ] {
        let view = view(&scene, Vec3::ZERO);
        let facets = facets(&view);
        // The prepass's depth: the G-buffer's, but on every eleventh pixel another
        // surface's 0.5 % nearer or farther (a cut-out, a culled back face): not trusted
        // there, the G-buffer normal's rules decide.
        let depths: Vec<f32> = view
            .depth
            .iter()
            .enumerate()
            .map(|(i, &d)| match i % 11 {
                4 => d * 1.005,
                9 => d * 0.995,
                _ => d,
            })
            .collect();
        for (light_name, light) in lights(Vec3::ZERO, EYE).into_iter().take(lights_run) {
            let plain = gpu_mask_at(&gpu, &passes, &scene, &view, &light, Default::default());
            let got = gpu_mask_at(
                &gpu,
                &passes,
                &scene,
                &view,
                &light,
                MaskOptions {
                    facets: Some((&facets, &depths)),
                    ..Default::default()
                },
            );
            let want = reference_mask_with_facets(&scene, &view, &light, (&facets, &depths));
            let (mean, _, max) = compare(&got.values, &want);
            // The triangle, not the G-buffer normal, decides the own shadow: where the
            // light's disc lies wholly below the triangle's plane the pixel is dark, and
            // the facets change many pixels.
            let (mut below, mut dark_below, mut changed) = (0, 0, 0);
            let (mut untrusted, mut untrusted_changed) = (0, 0);
            for (i, f) in facets.iter().enumerate() {
                let differs = (got.values[i] - plain.values[i]).abs() > 1e-4;
                if (got.values[i] - plain.values[i]).abs() > 0.5 {
                    changed += 1;
                }
                if *f == Vec3::ZERO || view.depth[i] <= 0.0 {
                    continue;
                }
                // Another surface's depth: the pixel is shaded as without the prepass.
                if depths[i] != view.depth[i] {
                    untrusted += 1;
                    untrusted_changed += usize::from(differs);
                    continue;
                }
                let p = pixel_position(&view, i);
                // Pixels the light does not reach are not traced (1).
                if !light_reaches(&light, p) {
                    continue;
                }
                let (dir, _, tan_half) = shadow_ray(p, &light);
                let seen = if f.dot(p) > 0.0 { -*f } else { *f };
                if horizon(seen, dir, tan_half) == 0.0
                    && horizon(facing_the_eye(view.normal(i), p), dir, tan_half) > 0.5
                {
                    below += 1;
                    if got.values[i] == 0.0 {
                        dark_below += 1;
                    }
                }
            }
            eprintln!(
                "{name} {light_name}: GPU vs model mean {mean:.6}, max {max:.4}; {changed} \
                 pixels changed by the facets; {dark_below} of {below} lit by their \
                 G-buffer normal and below their triangle's horizon dark"
            );
            assert!(
                mean < 1e-4 && max < 0.05,
                "{name} {light_name}: {mean} {max}"
            );
            assert!(below > 100 && dark_below == below, "{name} {light_name}");
            assert!(changed > 200, "{name} {light_name}: {changed}");
            assert!(
                untrusted > 100 && untrusted_changed == 0,
                "{name} {light_name}: {untrusted_changed} of {untrusted} untrusted pixels changed"
            );
        }
    }
}

/// The contract scene with its torus's `clear` flags cleared (`TWO_SIDED`: read as a
/// solid, not a shell).
fn scene_with_torus_flags(set: u32, clear: u32) -> Scene {
    let mut scene = scene(Vec3::ZERO);
    for r in &mut scene.records {
        if r.kind() == penumbra_df_core::object::ShapeKind::Volume as u32 {
            r.0[27] = (r.0[27] | set) & !clear;
        }
    }
    scene
}

/// Camera-relative point of pixel `i` of `view`.
fn pixel_position(view: &View, i: usize) -> Vec3 {
    let size = glam::Vec2::new(WIDTH as f32, HEIGHT as f32);
    let pixel = glam::Vec2::new((i as u32 % WIDTH) as f32, (i as u32 / WIDTH) as f32);
    penumbra_reference::shadow_mask::position_from_depth(
        view.view_from_clip,
        view.world_from_view,
        size,
        pixel,
        view.depth[i],
    )
}
