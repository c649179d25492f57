//! CPU model of the global distance field's composition (`penumbra_df_core::clipmap`
//! keeps the books: windows, dirty regions, budget; this fills in the texels).
//!
//! A brick job composes `BRICK³` texels of one level: each texel holds the smallest
//! distance of the objects whose bounds, grown by the level's band, reach the brick
//! ("culled per brick against object bounds"), clamped to `± band` — or `band` when
//! none does — and **stored conservatively**: the texture's format rounds, and the
//! value is lowered by one quantum of the format first, so the stored value never
//! exceeds the composed one ([`store`]). A sampler ([`GlobalField::sample`]) reads the
//! finest level whose eight trilinear texels all lie in composed, valid bricks.
//!
//! **Bound.** Distances are 1-Lipschitz and the objects' distances are lower bounds of
//! the true distance (the baked volumes' outside bound, exact analytic shapes), so a
//! trilinear sample at `p` mixes values at texel centres within a texel diagonal `δ` of
//! `p`, each at most `d(p) + δ`: the field never reports more than the true distance
//! plus one texel diagonal (tested against exact distances) — but deeper inside a
//! surface than the band, where it reads `−band`: inside all the same.

pub mod scenarios;
#[cfg(test)]
mod tests;

use crate::df::{Atlas, object_distance};
use crate::shadow_mask::bounding_sphere;
use glam::Affine3A;
use glam::{IVec3, Vec3};
use penumbra_df_core::clipmap::{
    BRICK, BrickJob, ClipmapLayout, ClipmapState, ComposeJob, GlobalFieldView, composes,
    unorm8_quantum,
};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::heightfield::{HeightfieldRecord, HeightfieldTexture};
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, TILE_SIZE, encode, flags};
use penumbra_sdf::volume::f16;

/// How the clipmap textures store distances.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClipmapFormat {
    /// `R16Float`: the distance in metres.
    F16,
    /// `R8Unorm`: `½ + ½ d / band`, 256 levels over `± band` (what UE5, Godot 4 and Flax
    /// store).
    Unorm8,
}

impl ClipmapFormat {
    /// Bytes per texel.
    pub fn bytes(self) -> u32 {
        match self {
            ClipmapFormat::F16 => 2,
            ClipmapFormat::Unorm8 => 1,
        }
    }

    /// The largest rounding step of a value in `± band`, metres.
    pub fn quantum(self, band: f32) -> f32 {
        match self {
            // f16 has 10 mantissa bits: a step of 2⁻¹⁰ of the binade's base (≤ band).
            ClipmapFormat::F16 => band * (1.0 / 1024.0),
            ClipmapFormat::Unorm8 => unorm8_quantum(band),
        }
    }
}

/// The value a texel of distance `d` holds: clamped to `± band`, lowered by one
/// quantum, rounded to the format as the GPU rounds (to nearest), decoded. Never above
/// `min(d, band)`; at most two quanta below it.
pub fn store(format: ClipmapFormat, d: f32, band: f32) -> f32 {
    let x = d.clamp(-band, band) - format.quantum(band);
    match format {
        ClipmapFormat::F16 => f16::from_f32(x).to_f32(),
        ClipmapFormat::Unorm8 => {
            let u = (0.5 + 0.5 * x / band).clamp(0.0, 1.0);
            // floor(x + ½): WGSL's `round` goes to even, the shader does this.
            let q = (u * 255.0 + 0.5).floor() / 255.0;
            (q - 0.5) * 2.0 * band
        }
    }
}

/// One object of the scene for composition: its world bounds (infinite for unbounded
/// shapes) and its distance (a lower bound of the true distance, at least the distance
/// to the bounds outside them).
pub struct FieldObject<'a> {
    /// Min corner of the world bounds.
    pub min: Vec3,
    /// Max corner of the world bounds.
    pub max: Vec3,
    /// World distance at a point, metres.
    pub distance: Box<dyn Fn(Vec3) -> f32 + 'a>,
}

/// An analytic caster in world space with its exact distance: scenes for tests and
/// benches whose truth is known everywhere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnalyticCaster {
    /// A ball.
    Sphere {
        /// Centre, metres.
        centre: Vec3,
        /// Radius, metres.
        radius: f32,
    },
    /// An axis-aligned box.
    Cuboid {
        /// Centre, metres.
        centre: Vec3,
        /// Half extents, metres.
        half: Vec3,
    },
}

impl AnalyticCaster {
    /// The exact signed distance at `p`.
    pub fn distance(&self, p: Vec3) -> f32 {
        match *self {
            AnalyticCaster::Sphere { centre, radius } => (p - centre).length() - radius,
            AnalyticCaster::Cuboid { centre, half } => {
                let q = (p - centre).abs() - half;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
        }
    }

    /// World bounds (min, max).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        match *self {
            AnalyticCaster::Sphere { centre, radius } => (centre - radius, centre + radius),
            AnalyticCaster::Cuboid { centre, half } => (centre - half, centre + half),
        }
    }

    /// The dirty region of its appearing, vanishing or having been here.
    pub fn dirty(&self) -> penumbra_df_core::clipmap::DirtyBox {
        let (min, max) = self.bounds();
        penumbra_df_core::clipmap::DirtyBox { min, max }
    }

    /// As an object to compose.
    pub fn field_object(self) -> FieldObject<'static> {
        let (min, max) = self.bounds();
        FieldObject {
            min,
            max,
            distance: Box::new(move |p| self.distance(p)),
        }
    }
}

/// The objects of GPU object records that occlude in the global field: live, occluding
/// (`casts_occlusion`) and opaque to AO (transmissive casters — foliage — are left to the
/// objects' own near-field trace). Distances through [`object_distance`] (what the
/// compute pass evaluates), bounds from the records' bounding balls (unbounded shapes:
/// everywhere). World positions are the camera's plus camera-relative ones.
pub fn record_objects<'a>(
    records: &'a [ObjectRecord],
    camera: &'a CameraOrigin,
    atlas: &'a Atlas,
) -> Vec<FieldObject<'a>> {
    let camera_world = camera_world(camera);
    records
        .iter()
        .filter(|r| composes(r))
        .map(|r| {
            let (min, max) = match bounding_sphere(r, camera) {
                Some((c, radius)) => (camera_world + c - radius, camera_world + c + radius),
                None => (Vec3::NEG_INFINITY, Vec3::INFINITY),
            };
            FieldObject {
                min,
                max,
                distance: Box::new(move |p| object_distance(r, p - camera_world, camera, atlas)),
            }
        })
        .collect()
}

/// The world position of a camera origin.
pub fn camera_world(camera: &CameraOrigin) -> Vec3 {
    Vec3::from_array(camera.tile.map(|t| t as f32)) * TILE_SIZE + camera.offset
}

impl AnalyticCaster {
    /// As a GPU object record (live, occluding, visible).
    pub fn record(&self) -> ObjectRecord {
        let (centre, shape) = match *self {
            AnalyticCaster::Sphere { centre, radius } => (centre, CasterShape::Sphere { radius }),
            AnalyticCaster::Cuboid { centre, half } => {
                (centre, CasterShape::Cuboid { half_extents: half })
            }
        };
        encode(&ObjectDesc {
            world_from_local: Affine3A::from_translation(centre),
            shape,
            flags: flags::LIVE | flags::CASTS_OCCLUSION | flags::CASTS_SHADOWS | flags::VISIBLE,
        })
        .expect("finite analytic caster")
    }
}

/// A closed room: floor, ceiling and four walls of thickness `wall` around the interior
/// `[−half.x, half.x] × [0, 2 half.y] × [−half.z, half.z]` (metres).
pub fn closed_room(half: Vec3, wall: f32) -> Vec<AnalyticCaster> {
    let h = 0.5 * wall;
    let outer = half + wall;
    let slab = |centre: Vec3, half: Vec3| AnalyticCaster::Cuboid { centre, half };
    vec![
        slab(Vec3::new(0.0, -h, 0.0), Vec3::new(outer.x, h, outer.z)),
        slab(
            Vec3::new(0.0, 2.0 * half.y + h, 0.0),
            Vec3::new(outer.x, h, outer.z),
        ),
        slab(
            Vec3::new(half.x + h, half.y, 0.0),
            Vec3::new(h, half.y, outer.z),
        ),
        slab(
            Vec3::new(-half.x - h, half.y, 0.0),
            Vec3::new(h, half.y, outer.z),
        ),
        slab(
            Vec3::new(0.0, half.y, half.z + h),
            Vec3::new(half.x, half.y, h),
        ),
        slab(
            Vec3::new(0.0, half.y, -half.z - h),
            Vec3::new(half.x, half.y, h),
        ),
    ]
}

/// The exact distance of a scene of analytic casters (`+∞` when empty).
pub fn analytic_distance(casters: &[AnalyticCaster], p: Vec3) -> f32 {
    casters
        .iter()
        .map(|c| c.distance(p))
        .fold(f32::INFINITY, f32::min)
}

/// The clipmap textures: per level `resolution³` values in storage order (x fastest),
/// NaN where nothing was ever composed.
#[derive(Clone, Debug)]
pub struct GlobalField {
    /// The layout.
    pub layout: ClipmapLayout,
    /// The storage format.
    pub format: ClipmapFormat,
    /// Per level, the texels in storage order.
    pub texels: Vec<Vec<f32>>,
}

/// What one brick's composition cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ComposeStats {
    /// Objects that passed the brick's cull.
    pub objects: usize,
    /// Object distance evaluations (texels × culled objects).
    pub evaluations: usize,
}

impl GlobalField {
    /// Textures of NaN.
    pub fn new(layout: ClipmapLayout, format: ClipmapFormat) -> Self {
        let n = (layout.resolution as usize).pow(3);
        GlobalField {
            layout,
            format,
            texels: vec![vec![f32::NAN; n]; layout.levels as usize],
        }
    }

    fn index(&self, w: IVec3) -> usize {
        let s = self.layout.storage(w);
        let n = self.layout.resolution as i32;
        (s.x + n * (s.y + n * s.z)) as usize
    }

    /// The stored value of world texel `w` of level `level`.
    pub fn texel(&self, level: u32, w: IVec3) -> f32 {
        self.texels[level as usize][self.index(w)]
    }

    /// The field buffer as the GPU holds it (`penumbra_df_core::clipmap::texel_byte`):
    /// 8-bit codes of every stored texel (0 where none was composed). Only for
    /// [`ClipmapFormat::Unorm8`], the GPU's format.
    pub fn field_bytes(&self) -> Vec<u8> {
        let layout = &self.layout;
        let n = layout.resolution as i32;
        let mut bytes = vec![0u8; penumbra_df_core::clipmap::field_words(layout) as usize * 4];
        for level in 0..layout.levels {
            let band = layout.band(level);
            for (i, &v) in self.texels[level as usize].iter().enumerate() {
                if v.is_nan() {
                    continue;
                }
                let i = i as i32;
                let s = IVec3::new(i % n, (i / n) % n, i / (n * n));
                let (word, byte) = penumbra_df_core::clipmap::texel_byte(layout, level, s);
                let code = ((0.5 + 0.5 * v / band) * 255.0).round().clamp(0.0, 255.0);
                bytes[(4 * word + byte) as usize] = code as u8;
            }
        }
        bytes
    }

    /// The objects that can change brick `job`'s texels: bounds grown by the level's
    /// reach (band and dilation) reach a texel centre of the brick.
    pub fn cull<'o, 'a>(
        &self,
        job: BrickJob,
        objects: &'o [FieldObject<'a>],
    ) -> Vec<&'o FieldObject<'a>> {
        let (level, t) = (job.level, self.layout.texel(job.level));
        let reach = self.layout.reach(level);
        let lo = self.layout.texel_centre(level, job.brick * BRICK as i32);
        let hi = lo + (BRICK - 1) as f32 * t;
        objects
            .iter()
            .filter(|o| (o.min - reach).cmple(hi).all() && (o.max + reach).cmpge(lo).all())
            .collect()
    }

    /// Composes brick `job` from `objects` (the whole scene; culled here).
    pub fn compose(&mut self, job: BrickJob, objects: &[FieldObject]) -> ComposeStats {
        let near = self.cull(job, objects);
        let band = self.layout.band(job.level);
        let (reach, dilation) = (
            self.layout.reach(job.level),
            self.layout.dilation(job.level),
        );
        let b = BRICK as i32;
        let mut evaluations = 0;
        for i in 0..b * b * b {
            let w = job.brick * b + IVec3::new(i % b, (i / b) % b, i / (b * b));
            let c = self.layout.texel_centre(job.level, w);
            let d = near.iter().map(|o| (o.distance)(c)).fold(reach, f32::min) - dilation;
            evaluations += near.len();
            let at = self.index(w);
            self.texels[job.level as usize][at] = store(self.format, d, band);
        }
        ComposeStats {
            objects: near.len(),
            evaluations,
        }
    }

    /// Composes brick `job` from GPU object records as the compose pass does
    /// (`shaders/df/global_compose.wgsl`): positions relative to the job's tile
    /// ([`ComposeJob::new`]), a record kept when its bounding ball grown by the reach
    /// (band and dilation) meets the box of the brick's texel centres, distances by [`object_distance`].
    pub fn compose_records(
        &mut self,
        job: BrickJob,
        records: &[ObjectRecord],
        atlas: &Atlas,
    ) -> ComposeStats {
        self.compose_records_and_terrain(job, records, atlas, &HeightfieldTexture::default())
    }

    /// [`Self::compose_records`] with heightfields as the compose pass adds them: a
    /// terrain whose box grown by the reach meets the brick's texel-centre box adds its
    /// distance ([`HeightfieldTexture::distance`]) at every texel.
    pub fn compose_records_and_terrain(
        &mut self,
        job: BrickJob,
        records: &[ObjectRecord],
        atlas: &Atlas,
        terrain: &HeightfieldTexture,
    ) -> ComposeStats {
        let frame = ComposeJob::new(&self.layout, job);
        let camera = CameraOrigin {
            tile: frame.tile.to_array(),
            offset: Vec3::ZERO,
        };
        let t = self.layout.texel(job.level);
        let band = self.layout.band(job.level);
        let (reach, dilation) = (
            self.layout.reach(job.level),
            self.layout.dilation(job.level),
        );
        let (lo, hi) = (
            frame.first,
            frame.first + Vec3::splat((BRICK - 1) as f32 * t),
        );
        let kept: Vec<&ObjectRecord> = records
            .iter()
            .filter(|r| composes(r))
            .filter(|r| {
                bounding_sphere(r, &camera)
                    .is_none_or(|(c, radius)| (c.clamp(lo, hi) - c).length() <= radius + reach)
            })
            .collect();
        // Terrains in their own tile's frame, with the brick's first texel centre there.
        let terrains: Vec<(&HeightfieldRecord, Vec3)> = terrain
            .records
            .iter()
            .map(|h| {
                let first = (frame.tile - h.tile).as_vec3() * TILE_SIZE + frame.first;
                (h, first)
            })
            .filter(|(h, first)| {
                let (min, max) = h.aabb();
                (min - reach).cmple(*first + (hi - lo)).all() && (max + reach).cmpge(*first).all()
            })
            .collect();
        let b = BRICK as i32;
        for i in 0..b * b * b {
            let ijk = IVec3::new(i % b, (i / b) % b, i / (b * b));
            let p = frame.first + ijk.as_vec3() * t;
            let objects = kept
                .iter()
                .map(|r| object_distance(r, p, &camera, atlas))
                .fold(reach, f32::min);
            let d = terrains
                .iter()
                .map(|(h, first)| terrain.distance(h, *first + ijk.as_vec3() * t))
                .fold(objects, f32::min)
                - dilation;
            let at = self.index(job.brick * b + ijk);
            self.texels[job.level as usize][at] = store(self.format, d, band);
        }
        ComposeStats {
            objects: kept.len() + terrains.len(),
            evaluations: (kept.len() + terrains.len()) * (b * b * b) as usize,
        }
    }

    /// The field at `p`: trilinear in the finest level whose eight texels around `p`
    /// are all in valid bricks of `state`, with that level; `None` where no level has.
    pub fn sample(&self, state: &ClipmapState, p: Vec3) -> Option<(f32, u32)> {
        self.sample_from(state, p, 0)
    }

    /// [`GlobalField::sample`] from level `first` on.
    pub fn sample_from(&self, state: &ClipmapState, p: Vec3, first: u32) -> Option<(f32, u32)> {
        (first..self.layout.levels)
            .find_map(|level| self.sample_level(state, level, p).map(|d| (d, level)))
    }

    /// Whether `d`, read from level `level`, is the clamp (within the two quanta of
    /// [`store`]'s rounding below it): "at least the band".
    pub fn is_clamped(&self, level: u32, d: f32) -> bool {
        let band = self.layout.band(level);
        d >= band - 2.0 * self.format.quantum(band)
    }

    /// The finest level whose band reaches `radius` plus a texel diagonal (the coarsest
    /// when none does): there a cone of that radius reads every value below its radius
    /// from unclamped texels (trilinear weights reach a diagonal away), and a clamped
    /// value as open, which it is.
    pub fn level_for_radius(&self, radius: f32) -> u32 {
        (0..self.layout.levels)
            .find(|&l| self.layout.band(l) >= radius + 3f32.sqrt() * self.layout.texel(l))
            .unwrap_or(self.layout.levels - 1)
    }

    /// The field at camera-relative `p` as the GPU samples it: from level `first` on,
    /// the first level whose window holds `p`'s eight trilinear texels in valid bricks
    /// (`valid`: [`GlobalFieldView::valid_bits`]), with that level.
    pub fn sample_view(
        &self,
        view: &GlobalFieldView,
        valid: &[u32],
        p: Vec3,
        first: u32,
    ) -> Option<(f32, u32)> {
        (first..view.level_count).find_map(|level| {
            self.sample_view_level(view, valid, level, p)
                .map(|d| (d, level))
        })
    }

    fn sample_view_level(
        &self,
        view: &GlobalFieldView,
        valid: &[u32],
        level: u32,
        p: Vec3,
    ) -> Option<f32> {
        let l = &view.levels[level as usize];
        if l.ready == 0 {
            return None;
        }
        let u = (p + l.camera) / l.texel - 0.5;
        let n = view.resolution as i32;
        let w0 = u.floor();
        if !(w0.cmpge(Vec3::ZERO).all() && w0.cmplt(Vec3::splat((n - 1) as f32)).all()) {
            return None;
        }
        let f = u - w0;
        let w0 = w0.as_ivec3();
        let nb = view.bricks_per_side as i32;
        let mut sum = 0.0;
        for k in 0..8 {
            let o = IVec3::new(k & 1, (k >> 1) & 1, k >> 2);
            let s = (l.origin_mod + w0 + o) % n;
            let b = s / BRICK as i32;
            let bit = (b.x + nb * (b.y + nb * b.z)) as u32;
            let word = valid[(level * view.valid_words + bit / 32) as usize];
            if word >> (bit % 32) & 1 == 0 {
                return None;
            }
            let weight = Vec3::select(o.cmpeq(IVec3::ONE), f, 1.0 - f);
            let at = (s.x + n * (s.y + n * s.z)) as usize;
            sum += weight.x * weight.y * weight.z * self.texels[level as usize][at];
        }
        Some(sum)
    }

    /// The field at `p` in level `level` alone, if its texels there are valid.
    pub fn sample_level(&self, state: &ClipmapState, level: u32, p: Vec3) -> Option<f32> {
        let u = p / self.layout.texel(level) - 0.5;
        if !u.is_finite() || u.abs().max_element() > 1e9 {
            return None;
        }
        let w0 = u.floor().as_ivec3();
        let f = u - u.floor();
        let b = IVec3::splat(BRICK as i32);
        let mut sum = 0.0;
        for k in 0..8 {
            let o = IVec3::new(k & 1, (k >> 1) & 1, k >> 2);
            let w = w0 + o;
            if !state.is_valid(level, w.div_euclid(b)) {
                return None;
            }
            let weight = Vec3::select(o.cmpeq(IVec3::ONE), f, 1.0 - f);
            sum += weight.x * weight.y * weight.z * self.texel(level, w);
        }
        Some(sum)
    }
}
