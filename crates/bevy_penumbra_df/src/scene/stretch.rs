//! Non-uniform scale baked into a mesh caster's field ([`CasterStretch`]).
//!
//! A field read through a transform that scales its axes differently is only a bound:
//! a distance in the mesh's space times the smallest scale never overestimates the world
//! distance (`penumbra_df_core::object`'s `conservative_scale`), but it underestimates
//! it along the other axes, by the ratio of the scales. A march's penumbra is the
//! distance over the cone's radius, so every penumbra of such a caster darkens and
//! widens: exporters squash and stretch props freely (the palm tree's fronds are scaled
//! 0.72 along their length, and their penumbrae on the ground read 28 % too close).
//! Unreal keeps the bound. Penumbra bakes the anisotropy instead: a caster whose axis
//! scales differ by at most [`STRETCH_MAX_RATIO`] bakes its mesh scaled per axis by its
//! transform's column lengths over the largest of them, each rounded to an eighth of an
//! octave ([`STRETCH_STEPS_PER_OCTAVE`]), and places the field by the transform times the
//! inverse, all but uniform: distances are then exact at every angle to within the
//! rounding (at most a step, 9 %, between two axes; the bound covers that much). Scales
//! within about 4 % of each other round to none; instances whose scales jitter by a few
//! percent round to the same stretch and share its bake. Beyond that ratio
//! (a cube made a plank, a floor or a wall) the smallest scale is the part's thin axis,
//! along which the bound is exact, and a stretched bake would be as coarse across it as
//! along its length: the bound is kept. The stretch is decided when the caster first
//! asks for a bake and kept (a caster whose scale animates is not re-baked each frame;
//! the bound covers what its scale does later). Cost: a bake per distinct stretch (at
//! most 8 steps per axis); no more samples than the unstretched bake (its finest axes
//! coarsen to its coarsest, by at most the ratio).

use bevy::math::Affine3A;
use bevy::prelude::*;

/// A stretch's components are powers of two in steps of an eighth of an octave (9 %).
pub const STRETCH_STEPS_PER_OCTAVE: f32 = 8.0;

/// The most a caster's largest axis scale may exceed its smallest for the spread to be
/// baked into its field: 2 (see the module docs).
pub const STRETCH_MAX_RATIO: f32 = 2.0;

/// The per-axis scale a mesh caster's field was baked with (its mesh's positions
/// multiplied by it; `Vec3::ONE`: none): the field is placed by the caster's transform
/// times its inverse. Inserted with the caster's bake request; see the module docs.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq)]
pub struct CasterStretch(pub Vec3);

impl Default for CasterStretch {
    fn default() -> Self {
        Self(Vec3::ONE)
    }
}

impl CasterStretch {
    /// The stretch to bake for a caster placed by `transform`: its column lengths over
    /// the largest, each rounded to a power of two in [`STRETCH_STEPS_PER_OCTAVE`]
    /// steps, where they differ by at most [`STRETCH_MAX_RATIO`] times; `Vec3::ONE`
    /// otherwise, where they all round to 1, or for a degenerate or non-finite
    /// transform.
    pub fn for_transform(transform: &GlobalTransform) -> Self {
        let m = transform.affine().matrix3;
        let lengths = Vec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length());
        let largest = lengths.max_element();
        if !lengths.is_finite() || largest <= 0.0 || lengths.min_element() <= 1e-6 * largest {
            return Self::default();
        }
        if lengths.min_element() * STRETCH_MAX_RATIO < largest {
            return Self::default();
        }
        let steps = STRETCH_STEPS_PER_OCTAVE;
        let rounded = (lengths / largest)
            .to_array()
            .map(|r| ((r.log2() * steps).round() / steps).exp2());
        Self(Vec3::from_array(rounded))
    }

    /// Where a field baked with this stretch lies for a caster placed by `transform`.
    pub fn world_from_field(&self, transform: &GlobalTransform) -> Affine3A {
        if self.0 == Vec3::ONE || !self.0.is_finite() || self.0.min_element() <= 0.0 {
            return transform.affine();
        }
        transform.affine() * Affine3A::from_scale(self.0.recip())
    }

    /// A direction of the mesh's space in the stretched space the field is baked in.
    pub fn direction(&self, v: Vec3) -> Vec3 {
        (v * self.0).normalize_or(v)
    }
}

/// Where a caster's shape lies: its transform, times the inverse of its stretch for a
/// mesh's field (analytic shapes have none).
pub(crate) fn world_from_field(
    source: &super::CasterSource,
    transform: &GlobalTransform,
    stretch: Option<&CasterStretch>,
) -> Affine3A {
    match stretch {
        Some(s) if *source == super::CasterSource::Mesh => s.world_from_field(transform),
        _ => transform.affine(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn placed(scale: Vec3, rotation: Quat) -> GlobalTransform {
        GlobalTransform::from(
            Transform::from_xyz(1.0, 2.0, 3.0)
                .with_rotation(rotation)
                .with_scale(scale),
        )
    }

    #[test]
    fn a_non_uniform_scale_is_baked_and_the_rest_placed_uniformly() {
        let r = Quat::from_euler(EulerRot::XYZ, 0.3, -1.1, 0.7);
        // Uniform, or within 4 %; a cube made a plank or a floor: none.
        for s in [
            Vec3::splat(2.0),
            Vec3::new(1.0, 0.96, 1.0),
            Vec3::new(4.0, 1.0, 1.0),
            Vec3::new(10.0, 0.2, 10.0),
        ] {
            assert_eq!(
                CasterStretch::for_transform(&placed(s, r)).0,
                Vec3::ONE,
                "{s}"
            );
        }
        // A frond squashed along its length, a mirrored plank.
        for s in [Vec3::new(0.72, 1.0, 1.0), Vec3::new(-1.6, 1.0, 0.9)] {
            let t = placed(s, r);
            let stretch = CasterStretch::for_transform(&t);
            // Each component within half a step of the exact stretch.
            let want = s.abs() / s.abs().max_element();
            let off = (stretch.0 / want).to_array().map(|q| q.log2().abs());
            assert!(
                off.iter()
                    .all(|o| *o <= 0.5 / STRETCH_STEPS_PER_OCTAVE + 1e-4),
                "{s}: {}",
                stretch.0
            );
            assert_ne!(stretch.0, Vec3::ONE, "{s}");
            // The field's placement scales every axis alike to within a step: the world
            // distance is the field's distance times about one number.
            let m = stretch.world_from_field(&t).matrix3;
            let lengths = Vec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length());
            let step = (-1.0 / STRETCH_STEPS_PER_OCTAVE).exp2();
            assert!(
                lengths.min_element() >= step * lengths.max_element() - 1e-5,
                "{s}: {lengths}"
            );
            // A point of the mesh lands where the transform puts it.
            let p = Vec3::new(0.3, -0.2, 0.9);
            let q = stretch.world_from_field(&t).transform_point3(p * stretch.0);
            assert!(q.abs_diff_eq(t.transform_point(p), 1e-4), "{s}");
        }
        // Degenerate or non-finite: none.
        for s in [Vec3::new(0.0, 1.0, 1.0), Vec3::new(f32::NAN, 1.0, 1.0)] {
            assert_eq!(
                CasterStretch::for_transform(&placed(s, r)).0,
                Vec3::ONE,
                "{s}"
            );
        }
    }
}
