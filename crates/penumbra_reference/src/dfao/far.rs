//! DFAO's far field: object distance fields near the surface, the **global distance
//! field** beyond a switch distance (Wright 2015: "object SDFs near the start of a cone,
//! the global field for the rest"; UE4's DFAO).
//!
//! Each cone marches the objects within reach of `switch_distance` only (so a pixel
//! visits the few objects near it, not every object within `max_distance`), then the
//! global field from `switch_distance` to `max_distance`: the same sphere tracing and
//! approximate cone intersection (`d / r`, with `r` capped by the sample's height above
//! the receiver's plane), without the objects' small-object floor (the field has no
//! bounding radii). A cone's visibility is the smaller of the two parts, shaped alike.
//! Each sample reads the finest valid level whose band (the clamp of its stored
//! distances) reaches the cone's radius there, so that a clamped value — "at least the
//! band" — means open: wider cones read coarser levels, as UE4's do.
//! Where no clipmap level is valid (the frames after a teleport), a far sample counts as
//! open: the far field fades in as the bricks are composed.
//!
//! Transmissive casters (foliage) are left out of the global field
//! ([`crate::global_sdf::record_objects`]): they occlude only within the switch
//! distance.

use super::{AoSample, combine, cone_visibilities, texture_visibilities};
use crate::df::Atlas;
use crate::global_sdf::GlobalField;
use glam::DVec3;
use glam::Vec3;
use penumbra_df_core::ao::{AoTrace, MIN_STEP_FRACTION, cone_axis, cone_tan_half, tangent_frame};
use penumbra_df_core::clipmap::{ClipmapState, GlobalFieldView};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::heightfield::HeightfieldTexture;
use penumbra_df_core::object::ObjectRecord;

/// The global field a far-field trace reads: the clipmaps, the view of them from the
/// camera and the validity bits, as the GPU binds them.
pub struct FarField<'a> {
    /// The clipmap textures.
    pub field: &'a GlobalField,
    /// The clipmaps from the camera (positions are camera-relative).
    pub view: GlobalFieldView,
    /// Every level's validity bits ([`GlobalFieldView::valid_bits`]).
    pub valid: Vec<u32>,
    /// Object distance fields up to here along each cone, the global field beyond,
    /// metres.
    pub switch_distance: f32,
    /// The finest level a sample may read (0 in use; measurements force coarser ones).
    pub min_level: u32,
}

impl<'a> FarField<'a> {
    /// The far field of `field` and `state`'s windows from a camera at `camera_world`.
    pub fn new(
        field: &'a GlobalField,
        state: &ClipmapState,
        camera_world: DVec3,
        switch_distance: f32,
    ) -> FarField<'a> {
        FarField {
            field,
            view: GlobalFieldView::new(state, camera_world),
            valid: GlobalFieldView::valid_bits(state),
            switch_distance,
            min_level: 0,
        }
    }
}

/// One cone's visibility through the global field from `far.switch_distance` to the
/// trace's max distance (origin `o`, camera-relative), and the field samples it took.
pub fn march_field(
    far: &FarField,
    o: Vec3,
    axis: Vec3,
    rise: f32,
    tan_half: f32,
    trace: &AoTrace,
) -> (f32, u32) {
    let mut t = far.switch_distance.max(trace.bias);
    let mut v = 1.0f32;
    let mut samples = 0;
    for _ in 0..trace.steps_per_cone {
        if t >= trace.max_distance {
            break;
        }
        let cone = (t * tan_half).max(1e-6);
        let open = cone.min(trace.bias + t * rise).max(1e-6);
        let p = o + axis * t;
        samples += 1;
        let first = far.field.level_for_radius(open).max(far.min_level);
        let Some((d, level)) = far.field.sample_view(&far.view, &far.valid, p, first) else {
            t += cone * MIN_STEP_FRACTION;
            continue;
        };
        // Surfaces are grown by the level's dilation so that thin walls have an inside;
        // inside means shut — unless the receiver's own (grown) tangent plane alone
        // would read as low (within a quarter texel: the storage's rounding), for a
        // sample that low over it is swallowed by the plane's growth, not by an
        // occluder. The penumbra takes the distance to the surface itself.
        let layout = &far.field.layout;
        let dilation = layout.dilation(level);
        let own_plane = trace.bias + t * rise - dilation;
        if d <= 0.0 && d < own_plane - 0.25 * layout.texel(level) {
            v = 0.0;
            break;
        }
        // A value at the clamp says only "at least the band": open, when the band
        // reaches the cone's radius (the level was chosen so, but for the coarsest).
        if !far.field.is_clamped(level, d) {
            v = v.min(((d + dilation) / open).max(0.0));
        }
        // Never farther than `d + 2 × dilation`: a grown wall is at least that thick
        // along the ray beyond its lower bound `d`, so no step passes through one.
        t += d
            .max(cone * MIN_STEP_FRACTION)
            .min(d.max(0.0) + 2.0 * dilation)
            .max(1e-3);
    }
    (v.clamp(0.0, 1.0).powf(trace.shaping), samples)
}

/// The AO at camera-relative `p` (unit normal `n`): objects within the switch distance,
/// the global field beyond. Returns the sample, the object distance evaluations and the
/// global field samples.
pub fn pixel_ao_far(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
    far: &FarField,
) -> (AoSample, u32, u32) {
    pixel_ao_far_filtered(
        records,
        atlas,
        camera,
        p,
        n,
        trace,
        Some(far),
        &NO_TERRAIN,
        |_| true,
    )
}

/// The AO at camera-relative `p` (unit normal `n`) as the trace pass computes it with
/// terrains bound (and the far field, where given): objects and terrains up to the
/// switch distance (the max distance without a far field), the field beyond. Returns
/// the sample, the distance evaluations and the field samples.
#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
pub fn pixel_ao_with_terrain(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
    far: Option<&FarField>,
    terrain: &HeightfieldTexture,
) -> (AoSample, u32, u32) {
    pixel_ao_far_filtered(records, atlas, camera, p, n, trace, far, terrain, |_| true)
}

/// No terrain.
static NO_TERRAIN: HeightfieldTexture = HeightfieldTexture {
    width: 0,
    rows: 0,
    texels: Vec::new(),
    records: Vec::new(),
};

/// The objects' part of a far-field trace: `trace` up to the switch distance.
fn near_trace(trace: &AoTrace, far: Option<&FarField>) -> AoTrace {
    let Some(far) = far else {
        return *trace;
    };
    AoTrace {
        max_distance: trace.max_distance.min(far.switch_distance.max(0.0)),
        ..*trace
    }
}

#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
fn pixel_ao_far_filtered(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
    far: Option<&FarField>,
    terrain: &HeightfieldTexture,
    keep: impl Fn(usize) -> bool,
) -> (AoSample, u32, u32) {
    let near = near_trace(trace, far);
    let (mut visibility, mut evaluations) =
        cone_visibilities(records, atlas, camera, p, n, &near, keep);
    let (terrain, e) = texture_visibilities(terrain, camera, p, n, &near);
    evaluations += e;
    for (v, t) in visibility.iter_mut().zip(terrain) {
        *v = v.min(t);
    }
    let Some(far) = far else {
        return (combine(&visibility, n), evaluations, 0);
    };
    let count = trace.cone_count;
    let tan_half = cone_tan_half(count);
    let (t, b) = tangent_frame(n);
    let o = p + n * trace.bias;
    let mut samples = 0;
    if far.switch_distance < trace.max_distance {
        for (k, v) in visibility.iter_mut().enumerate() {
            let a = cone_axis(k as u32, count);
            let axis = t * a.x + b * a.y + n * a.z;
            let (cone, s) = march_field(far, o, axis, a.z, tan_half, trace);
            *v = v.min(cone);
            samples += s;
        }
    }
    (combine(&visibility, n), evaluations, samples)
}

/// The trace pass over a view with the far field (`shaders/df/ao_trace.wgsl` with a
/// global distance field bound): [`super::trace_view`]'s tiles, culled with the objects'
/// part's influence (up to the switch distance), each texel's cones going on through
/// the field. Returns the texels, the object distance evaluations and the field
/// samples.
#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
pub fn trace_view_far(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    view: &super::AoView,
    divisor: u32,
    jitter: glam::UVec2,
    trace: &AoTrace,
    far: &FarField,
) -> (Vec<glam::Vec4>, u64, u64) {
    trace_view_with_terrain(
        records,
        atlas,
        camera,
        view,
        (divisor, jitter),
        trace,
        Some(far),
        &NO_TERRAIN,
    )
}

/// The trace pass with terrains bound (and the far field, where given): each cone also
/// marches every terrain ([`super::texture_visibilities`]) up to the switch distance
/// (the max distance without a far field). Returns the texels, the distance evaluations
/// (objects and terrains) and the field samples.
#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
pub fn trace_view_with_terrain(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    view: &super::AoView,
    (divisor, jitter): (u32, glam::UVec2),
    trace: &AoTrace,
    far: Option<&FarField>,
    terrain: &HeightfieldTexture,
) -> (Vec<glam::Vec4>, u64, u64) {
    let size = penumbra_df_core::ao::trace_size(view.size, divisor);
    let mut out = vec![glam::Vec4::new(1.0, 0.0, 0.0, 0.0); (size.x * size.y) as usize];
    let (mut evaluations, mut samples) = (0u64, 0u64);
    let influence = near_trace(trace, far).influence();
    super::for_each_tile_texel(
        records,
        atlas,
        camera,
        view,
        (divisor, jitter),
        influence,
        |texel, p, n, kept| {
            let (s, e, f) =
                pixel_ao_far_filtered(records, atlas, camera, p, n, trace, far, terrain, |slot| {
                    kept[slot]
                });
            evaluations += u64::from(e);
            samples += u64::from(f);
            out[(texel.y * size.x + texel.x) as usize] = s.to_vec4();
        },
    );
    (out, evaluations, samples)
}

#[cfg(test)]
mod tests {
    use super::super::tests::{defaults, ground, object};
    use super::*;
    use crate::dfao::pixel_ao_counted;
    use crate::global_sdf::{ClipmapFormat, record_objects};
    use glam::Affine3A;
    use penumbra_df_core::clipmap::ClipmapLayout;
    use penumbra_df_core::object::CasterShape;

    /// The global field of `records` around a camera at the origin, composed whole.
    fn field_of(records: &[ObjectRecord], atlas: &Atlas) -> (GlobalField, ClipmapState) {
        let layout = ClipmapLayout::DEFAULT;
        let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
        let objects = record_objects(records, &camera, atlas);
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, ClipmapFormat::F16);
        for job in state.update(Vec3::ZERO, &[], usize::MAX).jobs {
            field.compose(job, &objects);
        }
        (field, state)
    }

    /// A sphere of radius R, its centre D above a point of a plane, hides `(R / D)²` of
    /// the cosine-weighted hemisphere. With the switch at 1 m the spheres 2–6 m up are
    /// seen through the global field only: within 0.16 of the analytic value on average
    /// — the objects' own trace is within 0.1 (the approximate cone intersection's error
    /// under a ball half as wide as it is high), and the field's dilation (which keeps
    /// thin walls opaque) darkens by at most 0.08 more, never less — where ignoring the
    /// far field errs by 0.25.
    #[test]
    fn far_spheres_seen_through_the_global_field_match_the_analytic_occlusion() {
        let atlas = Atlas::new(glam::UVec3::ONE);
        let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
        let (mut far_sum, mut near_sum, mut blind_sum) = (0.0f32, 0.0f32, 0.0f32);
        let mut worst_apart = 0.0f32;
        let ds = [2.0f32, 3.0, 4.0, 6.0];
        for d in ds {
            let radius = 0.5 * d;
            let records = [
                ground(),
                object(
                    CasterShape::Sphere { radius },
                    Affine3A::from_translation(Vec3::new(0.0, d, 0.0)),
                ),
            ];
            let (field, state) = field_of(&records, &atlas);
            let far = FarField::new(&field, &state, DVec3::ZERO, 1.0);
            let want = 1.0 - (radius / d).powi(2);
            let p = Vec3::new(0.05, 0.0, -0.03);
            let (s, evaluations, samples) =
                pixel_ao_far(&records, &atlas, &camera, p, Vec3::Y, &defaults(), &far);
            assert!(samples > 0 && evaluations > 0);
            let (all, _) = pixel_ao_counted(&records, &atlas, &camera, p, Vec3::Y, &defaults());
            far_sum += (s.ao - want).abs() / ds.len() as f32;
            worst_apart = worst_apart.max((s.ao - all.ao).abs());
            assert!(
                s.ao <= all.ao + 0.01,
                "{d}: far {} objects {}",
                s.ao,
                all.ao
            );
            near_sum += (all.ao - want).abs() / ds.len() as f32;
            blind_sum += (1.0 - want) / ds.len() as f32;
            assert!(s.bent_normal.y > 0.99, "{d}: {}", s.bent_normal);
        }
        eprintln!(
            "far field {far_sum:.4}, objects only {near_sum:.4}, blind {blind_sum:.4}, \
             far against objects {worst_apart:.4}"
        );
        assert!(
            far_sum < 0.16 && near_sum < 0.1 && worst_apart < 0.08 && blind_sum > 0.2,
            "{far_sum} {near_sum} {blind_sum} {worst_apart}"
        );
    }

    /// Thin walls: inside a closed 4 × 2.5 × 4 m room of 5 cm walls every ray meets a
    /// wall within 5 m (truth: AO 0). Through the near clipmaps (levels 0 and 1 of the
    /// default layout) the far field lets no sky in — AO at most 0.05 at four receivers
    /// whose walls are beyond the 1 m switch, with the samples in their own levels and
    /// forced to level 1 — where a field without the dilation lets 0.5 of it in. (The
    /// objects' own march leaks such walls too — `benches/global_sdf.rs`, "objects
    /// only" — which within the switch distance the field does not mend.)
    #[test]
    fn a_closed_room_of_thin_walls_lets_no_sky_in_through_the_near_clipmaps() {
        use crate::global_sdf::{FieldObject, closed_room};
        let atlas = Atlas::new(glam::UVec3::ONE);
        let camera_world = Vec3::new(0.0, 1.2, 0.0);
        let camera = CameraOrigin::at(camera_world).expect("finite");
        let room = closed_room(Vec3::new(2.0, 1.25, 2.0), 0.05);
        let records: Vec<ObjectRecord> = room.iter().map(|c| c.record()).collect();
        // At least 1.2 m from every wall they face: the walls are beyond the switch.
        let receivers = [
            (Vec3::new(0.0, 0.0, 0.0), Vec3::Y),
            (Vec3::new(0.6, 0.0, -0.7), Vec3::Y),
            (Vec3::new(2.0, 1.2, 0.3), -Vec3::X),
            (Vec3::new(-0.5, 2.5, 0.5), -Vec3::Y),
        ];
        let ao = |dilation_texels: f32, min_level: u32| {
            let layout = ClipmapLayout {
                levels: 2,
                dilation_texels,
                ..ClipmapLayout::DEFAULT
            };
            let objects: Vec<FieldObject> = room.iter().map(|c| c.field_object()).collect();
            let mut state = ClipmapState::new(layout);
            let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
            for job in state.update(camera_world, &[], usize::MAX).jobs {
                field.compose(job, &objects);
            }
            let far = FarField {
                min_level,
                ..FarField::new(&field, &state, camera_world.as_dvec3(), 1.0)
            };
            receivers
                .iter()
                .map(|&(p, n)| {
                    let p = p - camera_world;
                    pixel_ao_far(&records, &atlas, &camera, p, n, &defaults(), &far)
                        .0
                        .ao
                })
                .fold(0.0f32, f32::max)
        };
        let dilation = ClipmapLayout::DEFAULT.dilation_texels;
        let (own, level1, bare) = (ao(dilation, 0), ao(dilation, 1), ao(0.0, 0));
        eprintln!(
            "room of 5 cm walls: worst AO {own:.3} (level ≥ 1: {level1:.3}; no dilation {bare:.3})"
        );
        assert!(
            own <= 0.05 && level1 <= 0.05 && bare > 0.3,
            "{own} {level1} {bare}"
        );
    }

    /// A switch at the max distance never reads the field: the objects' trace exactly.
    #[test]
    fn a_switch_beyond_the_reach_is_the_object_trace() {
        let atlas = Atlas::new(glam::UVec3::ONE);
        let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
        let records = [
            ground(),
            object(
                CasterShape::Cuboid {
                    half_extents: Vec3::new(1.0, 2.0, 0.3),
                },
                Affine3A::from_translation(Vec3::new(1.5, 2.0, 0.0)),
            ),
        ];
        let (field, state) = field_of(&records, &atlas);
        let far = FarField::new(&field, &state, DVec3::ZERO, 10.0);
        let (s, _, samples) = pixel_ao_far(
            &records,
            &atlas,
            &camera,
            Vec3::ZERO,
            Vec3::Y,
            &defaults(),
            &far,
        );
        let (want, _) =
            pixel_ao_counted(&records, &atlas, &camera, Vec3::ZERO, Vec3::Y, &defaults());
        assert_eq!(samples, 0);
        assert_eq!(s, want);
    }

    /// An open plane stays open through the field: the cones clear the receiver's own
    /// surface in the global field as they do in its object field, but for the
    /// conservative storage's quantum — from a switch distance where the cones are
    /// higher above the receiver than its level-0 dilation (0.17 m; at a switch of 0 the
    /// grown plane swallows the first samples: `FarField::switch_distance`).
    #[test]
    fn an_open_plane_is_open_through_the_field() {
        let atlas = Atlas::new(glam::UVec3::ONE);
        let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
        let records = [ground()];
        let (field, state) = field_of(&records, &atlas);
        for (switch_distance, floor) in [(0.5, 0.995), (1.0, 0.995), (2.0, 0.999)] {
            let far = FarField::new(&field, &state, DVec3::ZERO, switch_distance);
            let (s, _, samples) = pixel_ao_far(
                &records,
                &atlas,
                &camera,
                Vec3::new(0.3, 0.0, 0.7),
                Vec3::Y,
                &defaults(),
                &far,
            );
            assert!(samples > 0);
            assert!(s.ao > floor, "switch {switch_distance}: {}", s.ao);
        }
    }
}
