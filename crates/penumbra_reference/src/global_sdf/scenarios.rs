//! The global field's update scenarios (#17 item 8), shared by the `global_sdf` bench
//! (bricks and distance evaluations per frame on the CPU model) and the compose pass's
//! timing on the GPU (`bevy_penumbra_df`'s `global_sdf_gpu` test, `--ignored`): a town
//! of 1,000 analytic casters over 400 × 400 m — 600 buildings (boxes 2–12 m wide,
//! 3–20 m tall) and 400 props (balls of 0.3–2 m) — on a ground slab; a camera starting
//! at its centre, 1.7 m up; 60 frames a second.

use super::AnalyticCaster;
use glam::Vec3;
use penumbra_df_core::clipmap::DirtyBox;
use penumbra_testkit::XorShift as Rng;

/// The teleport scenario's name: from the town's centre to near a corner.
pub const TELEPORT: &str = "teleport, 212 m across the town";

/// A frame, seconds.
pub const DT: f32 = 1.0 / 60.0;

/// Where the camera starts.
pub const START: Vec3 = Vec3::new(0.0, 1.7, 0.0);

/// The town.
pub fn town() -> Vec<AnalyticCaster> {
    let mut rng = Rng(0x2545_f491);
    let mut out = vec![AnalyticCaster::Cuboid {
        centre: Vec3::new(0.0, -0.5, 0.0),
        half: Vec3::new(200.0, 0.5, 200.0),
    }];
    for i in 0..1000 {
        let (x, z) = (rng.range(-195.0, 195.0), rng.range(-195.0, 195.0));
        out.push(if i < 600 {
            let h = rng.range(3.0, 20.0);
            AnalyticCaster::Cuboid {
                centre: Vec3::new(x, 0.5 * h, z),
                half: Vec3::new(rng.range(1.0, 6.0), 0.5 * h, rng.range(1.0, 6.0)),
            }
        } else {
            let r = rng.range(0.3, 2.0);
            AnalyticCaster::Sphere {
                centre: Vec3::new(x, r, z),
                radius: r,
            }
        });
    }
    out
}

/// One frame of a scenario: `step(frame, camera, casters)` moves the camera and the
/// casters and returns the dirty regions.
pub type Step = Box<dyn FnMut(usize, &mut Vec3, &mut Vec<AnalyticCaster>) -> Vec<DirtyBox>>;

/// A scenario: its name, its frames, and a maker of its step.
pub type Scenario = (&'static str, usize, fn() -> Step);

/// Still camera, walk at 5 m/s, flight at 30 m/s, one and 100 casters moving at 2 m/s,
/// a teleport.
pub fn scenarios() -> Vec<Scenario> {
    vec![
        ("still camera", 300, || Box::new(|_, _, _| Vec::new())),
        ("walk, 5 m/s", 600, || {
            Box::new(move |_, c: &mut Vec3, _| {
                *c += Vec3::new(0.8, 0.0, 0.6) * 5.0 * DT;
                Vec::new()
            })
        }),
        ("flight, 30 m/s", 600, || {
            Box::new(move |f, c: &mut Vec3, _| {
                let a = f as f32 * DT * 0.3;
                *c += Vec3::new(a.cos(), 0.05, a.sin()) * 30.0 * DT;
                Vec::new()
            })
        }),
        ("one caster moving, 2 m/s", 300, || {
            Box::new(move |f, _, casters: &mut Vec<AnalyticCaster>| {
                let old = casters[1];
                let a = f as f32 * DT * 2.0 / 5.0;
                casters[1] = AnalyticCaster::Sphere {
                    centre: Vec3::new(5.0 * a.cos(), 1.0, 5.0 * a.sin()),
                    radius: 1.0,
                };
                vec![old.dirty(), casters[1].dirty()]
            })
        }),
        ("100 casters moving, 2 m/s", 300, || {
            Box::new(move |f, _, casters: &mut Vec<AnalyticCaster>| {
                let mut dirty = Vec::new();
                for i in 0..100 {
                    let old = casters[i + 1];
                    let a = f as f32 * DT * 2.0 / 8.0 + i as f32;
                    let r = 8.0 + (i % 10) as f32 * 6.0;
                    casters[i + 1] = AnalyticCaster::Sphere {
                        centre: Vec3::new(r * a.cos(), 1.0, r * a.sin()),
                        radius: 1.0,
                    };
                    dirty.extend([old.dirty(), casters[i + 1].dirty()]);
                }
                dirty
            })
        }),
        (TELEPORT, 120, || {
            Box::new(|f, c: &mut Vec3, _| {
                if f == 0 {
                    *c += Vec3::new(150.0, 0.0, -150.0);
                }
                Vec::new()
            })
        }),
    ]
}
