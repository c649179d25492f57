//! The bookkeeping of Penumbra's **global distance field**: camera-centred clipmaps of
//! the whole scene's distance, composited from the object SDFs and updated
//! incrementally (Wright, *Dynamic Occlusion with Signed Distance Fields*, SIGGRAPH
//! 2015: "composite into a global distance field"; UE4's global distance field).
//!
//! **Layout** ([`ClipmapLayout`]). `levels` cubes of `resolution³` texels, level `L`
//! covering `first_extent · growth^L` metres around the camera. A texel stores the
//! scene's distance at its centre, less a dilation (surfaces grown by half a texel
//! diagonal, so that walls thinner than a texel stay opaque), clamped to `± band`
//! (`band_texels` texels of its level): far from every surface the stored value is `band`, a valid lower bound of
//! the distance for a sphere tracer, and an object's influence ends `band` past its
//! bounds.
//!
//! **Addressing.** Texels are named by *world texel coordinates* `w` (the texel whose
//! centre is `(w + ½) · texel`); a level's window is the `resolution³` texels from its
//! origin `o`, and `w` is stored at `w mod resolution` (toroidal addressing), so a
//! window that moves keeps every texel it still covers where it was. The window moves
//! in whole **bricks** (`BRICK³` texels), the unit of every update: a brick of the world
//! is a brick of the texture (`resolution` is a multiple of `BRICK`).
//!
//! **Updates** ([`ClipmapState::update`], once a frame). A brick needs composing when the
//! window moves onto it (the newly revealed slabs) and when a caster's **dirty region**
//! covers it: the old and the new bounds of a caster that moved, appeared or vanished,
//! grown by the band (and the dilation, [`ClipmapLayout::reach`]). Such bricks are *pending*: out of date until composed, and the
//! update hands back at most `budget` of them per frame (nearest the camera first,
//! finest level first), so a teleport spreads over frames. A pending brick is marked
//! invalid at once — in [`ClipmapState::valid_bits`], which a sampler reads — so a stale
//! brick is never used: a sampler takes the finest level whose brick at that point is
//! valid. Levels from the third on move their window less often (every `2^(L−1)`
//! frames, staggered); their dirty regions are marked at once all the same.
//!
//! Everything here is integer arithmetic on world texel coordinates (exact at any
//! distance from the origin within `i32` texels); the composition itself — the texels'
//! values — is the reference model's (`penumbra_reference::global_sdf`) and the compute
//! shader's.

pub mod debug;
#[cfg(test)]
mod tests;

use crate::cull::{CameraOrigin, bounding_sphere};
use crate::object::{ObjectRecord, TILE_SIZE, flags};
use encase::ShaderType;
use glam::{DVec3, IVec3, Vec3, Vec4};
use std::collections::BTreeSet;

/// Texels per brick side: the unit of scrolling, dirty regions and composition.
pub const BRICK: u32 = 8;
/// Bricks composed per frame at most, by default: 4,096 bricks are 2²¹ texels, a
/// quarter of four 128³ levels — UE4 recomposes all four (a teleport) in about 7 ms on
/// PS4-class GPUs, so under 2 ms there and a fraction of that on current ones. Enough
/// for a flight at 30 m/s and for 100 one-metre casters moving at once near the camera
/// (at most 768 and 3,894 bricks a frame in `benches/global_sdf.rs`); a teleport
/// across a town settles in 4 frames.
pub const DEFAULT_BRICK_BUDGET: usize = 4096;
/// Most clipmap levels.
pub const MAX_LEVELS: u32 = 8;
/// The largest resolution (texels per side): 256³ texels are 32 MiB at 16 bits.
pub const MAX_RESOLUTION: u32 = 256;
/// The smallest resolution: two bricks per side.
pub const MIN_RESOLUTION: u32 = 2 * BRICK;

/// The clipmaps' size and reach, validated ([`ClipmapLayout::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipmapLayout {
    /// Number of levels, `1..=MAX_LEVELS`.
    pub levels: u32,
    /// Texels per side of every level, a multiple of [`BRICK`] in
    /// `MIN_RESOLUTION..=MAX_RESOLUTION`.
    pub resolution: u32,
    /// Side of level 0's cube, metres (finite, positive).
    pub first_extent: f32,
    /// Each level's side over the previous one's (finite, ≥ 1).
    pub growth: f32,
    /// Stored distances are clamped to `± band_texels` texels of their level.
    pub band_texels: f32,
    /// Surfaces are grown by this many texels of their level when composed (the stored
    /// distance is lowered by it), so that a wall thinner than a texel still has texels
    /// inside it and stops far-field cones (`benches/global_sdf.rs`, thin walls).
    pub dilation_texels: f32,
}

impl ClipmapLayout {
    /// Four levels of 128³, the first 25.6 m across (0.2 m texels), each twice the last
    /// (the largest 204.8 m), distances clamped to ± 8 texels, surfaces grown by half a
    /// texel diagonal (every surface point then has a texel centre at or inside it).
    /// Chosen on `benches/global_sdf.rs`'s thin walls: with ± 4 texels and no growth a
    /// room of 40 cm walls lets far-field cones through (AO 0.21 where the truth is 0);
    /// these make 2 cm walls opaque through levels 0–2 for 0.06 more AO error on open
    /// ground (0.145 against 0.087).
    pub const DEFAULT: ClipmapLayout = ClipmapLayout {
        levels: 4,
        resolution: 128,
        first_extent: 25.6,
        growth: 2.0,
        band_texels: 8.0,
        dilation_texels: 0.866,
    };

    /// A layout from requested values, each out-of-range one replaced by the nearest
    /// valid value (a non-finite one by the default) and named in the returned
    /// problems, one line each, for the caller to warn with.
    pub fn new(
        levels: u32,
        resolution: u32,
        first_extent: f32,
        growth: f32,
    ) -> (Self, Vec<String>) {
        let d = Self::DEFAULT;
        let mut problems = Vec::new();
        let clamped_levels = levels.clamp(1, MAX_LEVELS);
        if clamped_levels != levels {
            problems.push(format!(
                "clipmap levels = {levels} is outside 1..={MAX_LEVELS}: using {clamped_levels}"
            ));
        }
        let r = resolution.clamp(MIN_RESOLUTION, MAX_RESOLUTION);
        let r = (r + BRICK / 2) / BRICK * BRICK;
        if r != resolution {
            problems.push(format!(
                "clipmap resolution = {resolution} is not a multiple of {BRICK} in \
                 {MIN_RESOLUTION}..={MAX_RESOLUTION}: using {r}"
            ));
        }
        let extent = if first_extent.is_finite() && first_extent > 0.0 {
            first_extent
        } else {
            problems.push(format!(
                "clipmap first extent = {first_extent} m is not a positive finite number: \
                 using {} m",
                d.first_extent
            ));
            d.first_extent
        };
        let g = if !growth.is_finite() {
            problems.push(format!(
                "clipmap growth = {growth} is not finite: using {}",
                d.growth
            ));
            d.growth
        } else if growth < 1.0 {
            problems.push(format!("clipmap growth = {growth} is below 1: using 1"));
            1.0
        } else {
            growth
        };
        let layout = ClipmapLayout {
            levels: clamped_levels,
            resolution: r,
            first_extent: extent,
            growth: g,
            band_texels: d.band_texels,
            dilation_texels: d.dilation_texels,
        };
        // The largest level's texel coordinates must fit in i32 however far the camera
        // goes (10⁷ m) — a texel below 10⁷ / 2³⁰ m, about 1 cm, at level 0.
        if layout.texel(0) < 0.01 {
            problems.push(format!(
                "clipmap texel = {} m is below 1 cm: using 1 cm texels",
                layout.texel(0)
            ));
            return (
                ClipmapLayout {
                    first_extent: 0.01 * r as f32,
                    ..layout
                },
                problems,
            );
        }
        if !layout.extent(layout.levels - 1).is_finite() {
            problems.push(format!("clipmap growth = {g} overflows: using 2"));
            return (
                ClipmapLayout {
                    growth: 2.0,
                    ..layout
                },
                problems,
            );
        }
        (layout, problems)
    }

    /// Side of level `level`'s cube, metres.
    pub fn extent(&self, level: u32) -> f32 {
        self.first_extent * self.growth.powi(level as i32)
    }

    /// Texel size of level `level`, metres.
    pub fn texel(&self, level: u32) -> f32 {
        self.extent(level) / self.resolution as f32
    }

    /// The clamp of level `level`'s stored distances, metres.
    pub fn band(&self, level: u32) -> f32 {
        self.band_texels * self.texel(level)
    }

    /// How much level `level` grows surfaces, metres.
    pub fn dilation(&self, level: u32) -> f32 {
        self.dilation_texels * self.texel(level)
    }

    /// How far an object's surface can change level `level`'s stored values: the band
    /// plus the dilation, metres. Culling and dirty regions grow bounds by it.
    pub fn reach(&self, level: u32) -> f32 {
        self.band(level) + self.dilation(level)
    }

    /// Bricks per side of a level.
    pub fn bricks_per_side(&self) -> u32 {
        self.resolution / BRICK
    }

    /// Bricks per level.
    pub fn bricks_per_level(&self) -> u32 {
        self.bricks_per_side().pow(3)
    }

    /// Texels of all levels together.
    pub fn texel_count(&self) -> u64 {
        u64::from(self.resolution).pow(3) * u64::from(self.levels)
    }

    /// The origin (world texel coordinates of the min corner, a multiple of [`BRICK`])
    /// of level `level`'s window centred on `camera`: the camera is within half a brick
    /// of the window's centre (a brick, for an odd number of bricks per side). `None` for a non-finite camera or one too far out for
    /// `i32` texel coordinates.
    pub fn window_origin(&self, level: u32, camera: Vec3) -> Option<IVec3> {
        let brick = self.texel(level) * BRICK as f32;
        let b = (camera / brick).round();
        let limit = (i32::MAX / BRICK as i32 / 4) as f32;
        (b.is_finite() && b.abs().max_element() < limit).then(|| {
            (b.as_ivec3() - IVec3::splat(self.bricks_per_side() as i32 / 2)) * BRICK as i32
        })
    }

    /// World position of the centre of texel `w` of level `level`.
    pub fn texel_centre(&self, level: u32, w: IVec3) -> Vec3 {
        (w.as_vec3() + 0.5) * self.texel(level)
    }

    /// Where texel `w` is stored in its level's texture (toroidal addressing).
    pub fn storage(&self, w: IVec3) -> IVec3 {
        w.rem_euclid(IVec3::splat(self.resolution as i32))
    }

    /// The world bricks whose texel centres lie within `grow` metres of the box
    /// `[min, max]`, in level `level`, as a half-open box of brick coordinates (empty or
    /// `None` for a non-finite box).
    pub fn bricks_near(&self, level: u32, min: Vec3, max: Vec3, grow: f32) -> Option<BrickBox> {
        let t = self.texel(level);
        // Texel w's centre (w + ½)t lies in [min − grow, max + grow] when
        // w ∈ [ (min − grow)/t − ½, (max + grow)/t − ½ ].
        let lo = ((min - grow) / t - 0.5).ceil();
        let hi = ((max + grow) / t - 0.5).floor();
        let limit = (i32::MAX / 4) as f32;
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let lo = lo.clamp(Vec3::splat(-limit), Vec3::splat(limit)).as_ivec3();
        let hi = hi.clamp(Vec3::splat(-limit), Vec3::splat(limit)).as_ivec3();
        let b = BRICK as i32;
        Some(BrickBox {
            min: lo.div_euclid(IVec3::splat(b)),
            max: hi.div_euclid(IVec3::splat(b)) + IVec3::ONE,
        })
    }
}

impl Default for ClipmapLayout {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A half-open box `[min, max)` of world brick coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickBox {
    /// Inclusive corner.
    pub min: IVec3,
    /// Exclusive corner.
    pub max: IVec3,
}

impl BrickBox {
    /// The intersection (possibly empty).
    pub fn intersect(&self, o: &BrickBox) -> BrickBox {
        BrickBox {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    /// Whether it holds no brick.
    pub fn is_empty(&self) -> bool {
        self.max.cmple(self.min).any()
    }

    /// Whether it holds brick `b`.
    pub fn contains(&self, b: IVec3) -> bool {
        b.cmpge(self.min).all() && b.cmplt(self.max).all()
    }

    /// Every brick in it, z slowest.
    pub fn iter(&self) -> impl Iterator<Item = IVec3> + '_ {
        let (a, b) = (self.min, self.max);
        (a.z..b.z.max(a.z)).flat_map(move |z| {
            (a.y..b.y.max(a.y))
                .flat_map(move |y| (a.x..b.x.max(a.x)).map(move |x| IVec3::new(x, y, z)))
        })
    }
}

/// One brick to compose this frame: level and world brick coordinates (its texels are
/// `brick · BRICK + [0, BRICK)³`, stored at their toroidal address).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickJob {
    /// Clipmap level.
    pub level: u32,
    /// World brick coordinates.
    pub brick: IVec3,
}

/// What one frame's update did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClipmapUpdate {
    /// Bricks to compose now, in order; they are valid once composed.
    pub jobs: Vec<BrickJob>,
    /// Each level's window origin (world texel coordinates) after the update.
    pub origins: Vec<IVec3>,
    /// Bricks still pending after this frame's jobs (all levels).
    pub pending: usize,
    /// Bricks newly revealed by moving windows this frame.
    pub scrolled: usize,
    /// Bricks newly marked by dirty regions this frame.
    pub dirtied: usize,
}

/// A caster's region whose distances may have changed: its bounds before or after a
/// change (world space, metres). The update grows it by each level's band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirtyBox {
    /// Min corner.
    pub min: Vec3,
    /// Max corner.
    pub max: Vec3,
}

#[derive(Clone, Debug, Default)]
struct LevelState {
    /// Window origin in world texels; `None` until the first update.
    origin: Option<IVec3>,
    /// World bricks in the window awaiting composition (as arrays: ordered).
    pending: BTreeSet<[i32; 3]>,
}

/// The clipmaps' update state: every level's window and pending bricks.
#[derive(Clone, Debug)]
pub struct ClipmapState {
    layout: ClipmapLayout,
    levels: Vec<LevelState>,
    frame: u64,
}

impl ClipmapState {
    /// Nothing composed yet: the first update reveals every brick of every level.
    pub fn new(layout: ClipmapLayout) -> Self {
        ClipmapState {
            layout,
            levels: vec![LevelState::default(); layout.levels as usize],
            frame: 0,
        }
    }

    /// The layout.
    pub fn layout(&self) -> &ClipmapLayout {
        &self.layout
    }

    /// Level `level`'s window origin, once it has one.
    pub fn origin(&self, level: u32) -> Option<IVec3> {
        self.levels.get(level as usize)?.origin
    }

    /// Level `level`'s window as a box of world bricks.
    pub fn window(&self, level: u32) -> Option<BrickBox> {
        let o = self.origin(level)?;
        let b = BRICK as i32;
        let n = self.layout.bricks_per_side() as i32;
        Some(BrickBox {
            min: o.div_euclid(IVec3::splat(b)),
            max: o.div_euclid(IVec3::splat(b)) + IVec3::splat(n),
        })
    }

    /// Bricks awaiting composition, all levels.
    pub fn pending(&self) -> usize {
        self.levels.iter().map(|l| l.pending.len()).sum()
    }

    /// Whether world brick `brick` of level `level` is in the window and up to date.
    pub fn is_valid(&self, level: u32, brick: IVec3) -> bool {
        self.window(level).is_some_and(|w| w.contains(brick))
            && !self.levels[level as usize]
                .pending
                .contains(&brick.to_array())
    }

    /// Whether level `level` moves its window on frame `frame`: levels 0 and 1 every
    /// frame, level `L ≥ 2` every `2^(L−1)` frames, staggered so that few move at once.
    pub fn moves_on(level: u32, frame: u64) -> bool {
        let period = if level < 2 {
            1
        } else {
            1u64 << (level - 1).min(6)
        };
        (frame + u64::from(level)).is_multiple_of(period)
    }

    /// One frame: moves the windows towards `camera` (a non-finite camera moves none),
    /// marks the bricks the `dirty` boxes reach as pending (a non-finite box is
    /// ignored), and hands back at most `budget` pending bricks to compose now — nearest
    /// the camera first, finest level first. They count as composed from now on.
    pub fn update(&mut self, camera: Vec3, dirty: &[DirtyBox], budget: usize) -> ClipmapUpdate {
        let mut out = ClipmapUpdate::default();
        let layout = self.layout;
        for level in 0..layout.levels {
            let first = self.levels[level as usize].origin.is_none();
            if first || Self::moves_on(level, self.frame) {
                out.scrolled += self.scroll(level, camera);
            }
            let Some(window) = self.window(level) else {
                continue;
            };
            let state = &mut self.levels[level as usize];
            for d in dirty {
                let Some(bricks) = layout.bricks_near(level, d.min, d.max, layout.reach(level))
                else {
                    continue;
                };
                for b in bricks.intersect(&window).iter() {
                    out.dirtied += usize::from(state.pending.insert(b.to_array()));
                }
            }
        }
        out.jobs = self.take(camera, budget);
        out.origins = self
            .levels
            .iter()
            .map(|l| l.origin.unwrap_or(IVec3::ZERO))
            .collect();
        out.pending = self.pending();
        self.frame += 1;
        out
    }

    /// Moves level `level`'s window to `camera`: bricks that leave it are forgotten,
    /// bricks that enter it become pending. Returns how many entered.
    fn scroll(&mut self, level: u32, camera: Vec3) -> usize {
        let Some(origin) = self.layout.window_origin(level, camera) else {
            return 0;
        };
        let old = self.window(level);
        let state = &mut self.levels[level as usize];
        if state.origin == Some(origin) {
            return 0;
        }
        state.origin = Some(origin);
        let new = self.window(level).expect("origin was just set");
        let state = &mut self.levels[level as usize];
        state
            .pending
            .retain(|&b| new.contains(IVec3::from_array(b)));
        let mut entered = 0;
        for b in new.iter() {
            if old.is_none_or(|o| !o.contains(b)) {
                entered += usize::from(state.pending.insert(b.to_array()));
            }
        }
        entered
    }

    /// The `budget` pending bricks to compose first: finest level first, then nearest
    /// the camera's brick (Chebyshev distance), then by coordinates (deterministic).
    fn take(&mut self, camera: Vec3, budget: usize) -> Vec<BrickJob> {
        let mut jobs = Vec::new();
        for level in 0..self.layout.levels {
            if jobs.len() >= budget {
                break;
            }
            let state = &self.levels[level as usize];
            if state.pending.is_empty() {
                continue;
            }
            let brick = self.layout.texel(level) * BRICK as f32;
            let at = (camera / brick).floor();
            let at = if at.is_finite() {
                at.clamp(Vec3::splat(-1e9), Vec3::splat(1e9)).as_ivec3()
            } else {
                IVec3::ZERO
            };
            let mut order: Vec<(i64, IVec3)> = state
                .pending
                .iter()
                .map(|&b| {
                    let d = (IVec3::from_array(b).as_i64vec3() - at.as_i64vec3())
                        .abs()
                        .max_element();
                    (d, IVec3::from_array(b))
                })
                .collect();
            order.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.to_array().cmp(&b.1.to_array())));
            let state = &mut self.levels[level as usize];
            for (_, b) in order.into_iter().take(budget - jobs.len()) {
                state.pending.remove(&b.to_array());
                jobs.push(BrickJob { level, brick: b });
            }
        }
        jobs
    }

    /// Level `level`'s brick validity for a sampler: one bit per *storage* brick
    /// (`x + n·(y + n·z)`, `n` bricks per side, bit `i % 32` of word `i / 32`), set when
    /// the world brick stored there is in the window and composed.
    pub fn valid_bits(&self, level: u32) -> Vec<u32> {
        let n = self.layout.bricks_per_side() as i32;
        let count = self.layout.bricks_per_level() as usize;
        let mut words = vec![0u32; count.div_ceil(32)];
        let Some(window) = self.window(level) else {
            return words;
        };
        for b in window.iter() {
            if self.levels[level as usize].pending.contains(&b.to_array()) {
                continue;
            }
            let s = b.rem_euclid(IVec3::splat(n));
            let i = (s.x + n * (s.y + n * s.z)) as usize;
            words[i / 32] |= 1 << (i % 32);
        }
        words
    }
}

/// Whether a record goes into the global field: live, occluding, opaque to AO
/// (transmissive casters — foliage — stay out: they occlude only in the objects' own
/// near-field trace). The compose pass applies the same rule.
pub fn composes(r: &ObjectRecord) -> bool {
    let f = r.flags();
    f & flags::LIVE != 0 && flags::casts_occlusion(f) && flags::ao_transmission(f) == 0.0
}

/// The dirty region of a record that appears, vanishes or is overwritten: the box of
/// its bounding ball (what the compose pass culls with), in world metres, grown by a
/// millimetre and f32's rounding; everything for unbounded shapes; `None` for a record
/// that does not go into the field ([`composes`]).
pub fn record_dirty_box(r: &ObjectRecord) -> Option<DirtyBox> {
    if !composes(r) {
        return None;
    }
    let at_tile = CameraOrigin {
        tile: r.tile(),
        offset: Vec3::ZERO,
    };
    let Some((centre, radius)) = bounding_sphere(r, &at_tile) else {
        return Some(DirtyBox {
            min: Vec3::splat(-1e9),
            max: Vec3::splat(1e9),
        });
    };
    let tile = DVec3::from_array(r.tile().map(f64::from)) * f64::from(TILE_SIZE);
    let world = tile + centre.as_dvec3();
    let grow = f64::from(radius) + 1e-3 + 1e-6 * world.abs().max_element();
    Some(DirtyBox {
        min: (world - grow).as_vec3(),
        max: (world + grow).as_vec3(),
    })
}

/// One brick for the compose pass (`ComposeJob` in `shaders/df/global_compose.wgsl`):
/// where its texels are, in the object records' 512 m tiles, and where they go.
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct ComposeJob {
    /// The tile the positions are relative to (the brick's first texel's).
    pub tile: IVec3,
    /// Clipmap level.
    pub level: u32,
    /// Centre of the brick's first texel relative to `tile`, metres (from f64).
    pub first: Vec3,
    /// The brick's first word in the field buffer ([`brick_word`]).
    pub word: u32,
}

impl ComposeJob {
    /// The job of brick `job`: texel `(i, j, k)` of it sits at `first + (i, j, k) ·
    /// texel` relative to `tile` — computed in f64, so exact enough 10⁷ m out, and the
    /// same on every frame (a brick composed twice gets the same values).
    pub fn new(layout: &ClipmapLayout, job: BrickJob) -> ComposeJob {
        let t = f64::from(layout.texel(job.level));
        let w = (job.brick * BRICK as i32).as_dvec3();
        let centre = (w + DVec3::splat(0.5)) * t;
        let tile = (centre / f64::from(TILE_SIZE)).round();
        let first = centre - tile * f64::from(TILE_SIZE);
        ComposeJob {
            tile: tile.as_ivec3(),
            level: job.level,
            first: first.as_vec3(),
            word: brick_word(
                layout,
                job.level,
                layout.storage(job.brick * BRICK as i32) / BRICK as i32,
            ),
        }
    }
}

/// The compose pass's uniform (`ComposeParams` in `shaders/df/global_compose.wgsl`).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct ComposeParams {
    /// Per level: texel size, band, the storage quantum ([`unorm8_quantum`]), dilation.
    pub levels: [Vec4; MAX_LEVELS as usize],
    /// Object buffer slots to consider.
    pub slot_count: u32,
    /// Jobs in the job buffer.
    pub job_count: u32,
    /// Heightfield records to consider.
    pub heightfield_count: u32,
}

impl ComposeParams {
    /// The uniform of `layout` for `slot_count` object slots and `job_count` jobs.
    pub fn new(layout: &ClipmapLayout, slot_count: u32, job_count: u32) -> ComposeParams {
        let mut levels = [Vec4::ZERO; MAX_LEVELS as usize];
        for (l, v) in levels.iter_mut().enumerate().take(layout.levels as usize) {
            let band = layout.band(l as u32);
            let l = l as u32;
            *v = Vec4::new(
                layout.texel(l),
                band,
                unorm8_quantum(band),
                layout.dilation(l),
            );
        }
        ComposeParams {
            levels,
            slot_count,
            job_count,
            heightfield_count: 0,
        }
    }
}

/// Words (`u32`) per brick in the field buffer: 512 texels of one byte.
pub const BRICK_WORDS: u32 = BRICK * BRICK * BRICK / 4;

/// The field buffer's size in words: every level's bricks, brick after brick.
pub fn field_words(layout: &ClipmapLayout) -> u64 {
    u64::from(layout.levels) * u64::from(layout.bricks_per_level()) * u64::from(BRICK_WORDS)
}

/// The first word of storage brick `s` (`0 ≤ s < bricks per side`) of level `level`.
/// Within a brick texel `(i, j, k)` is byte `i % 4` of word `i / 4 + 2 (j + 8 k)`.
pub fn brick_word(layout: &ClipmapLayout, level: u32, s: IVec3) -> u32 {
    let n = layout.bricks_per_side() as i32;
    let brick = (s.x + n * (s.y + n * s.z)) as u32;
    (level * layout.bricks_per_level() + brick) * BRICK_WORDS
}

/// Where world texel `w` of level `level` is in the field buffer: word and byte.
pub fn texel_byte(layout: &ClipmapLayout, level: u32, w: IVec3) -> (u32, u32) {
    let s = layout.storage(w);
    let b = BRICK as i32;
    let inner = s.rem_euclid(IVec3::splat(b));
    let word =
        brick_word(layout, level, s / b) + (inner.x / 4 + 2 * (inner.y + b * inner.z)) as u32;
    (word, (inner.x % 4) as u32)
}

/// The rounding step of the 8-bit storage over `± band`: `2 band / 255`.
pub fn unorm8_quantum(band: f32) -> f32 {
    2.0 * band / 255.0
}

/// One level as a sampler reads it (`GlobalFieldLevel` in
/// `shaders/df/global_field.wgsl`).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct GlobalFieldLevel {
    /// The camera's position relative to the window's min corner, metres (f64 on the
    /// CPU: exact enough anywhere).
    pub camera: Vec3,
    /// Texel size, metres.
    pub texel: f32,
    /// The window's origin (world texels) modulo the resolution: where texel 0 of the
    /// window is stored.
    pub origin_mod: IVec3,
    /// The band, metres.
    pub band: f32,
    /// The dilation, metres.
    pub dilation: f32,
    /// The storage quantum ([`unorm8_quantum`]), metres.
    pub quantum: f32,
    /// 1 when the level has a window, 0 before its first update.
    pub ready: u32,
    /// Padding.
    pub _pad: u32,
}

/// The clipmaps as a sampler reads them, for one camera (`GlobalFieldView` in
/// `shaders/df/global_field.wgsl`): positions are camera-relative.
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct GlobalFieldView {
    /// Per level.
    pub levels: [GlobalFieldLevel; MAX_LEVELS as usize],
    /// Levels in use.
    pub level_count: u32,
    /// Texels per side.
    pub resolution: u32,
    /// Bricks per side.
    pub bricks_per_side: u32,
    /// Words of validity bits per level.
    pub valid_words: u32,
}

impl GlobalFieldView {
    /// The view of `state`'s windows from a camera at world position `camera` (f64).
    pub fn new(state: &ClipmapState, camera: DVec3) -> GlobalFieldView {
        let layout = state.layout();
        let n = layout.resolution as i32;
        let mut levels = [GlobalFieldLevel::default(); MAX_LEVELS as usize];
        for (l, v) in levels.iter_mut().enumerate().take(layout.levels as usize) {
            let level = l as u32;
            let texel = layout.texel(level);
            let band = layout.band(level);
            let origin = state.origin(level);
            let corner = origin.map_or(DVec3::ZERO, |o| o.as_dvec3() * f64::from(texel));
            *v = GlobalFieldLevel {
                camera: (camera - corner).as_vec3(),
                texel,
                origin_mod: origin.map_or(IVec3::ZERO, |o| o.rem_euclid(IVec3::splat(n))),
                band,
                dilation: layout.dilation(level),
                quantum: unorm8_quantum(band),
                ready: u32::from(origin.is_some()),
                _pad: 0,
            };
        }
        GlobalFieldView {
            levels,
            level_count: layout.levels,
            resolution: layout.resolution,
            bricks_per_side: layout.bricks_per_side(),
            valid_words: layout.bricks_per_level().div_ceil(32),
        }
    }

    /// Every level's [`ClipmapState::valid_bits`], level after level
    /// ([`GlobalFieldView::valid_words`] words each): the sampler's validity buffer.
    pub fn valid_bits(state: &ClipmapState) -> Vec<u32> {
        (0..state.layout().levels)
            .flat_map(|l| state.valid_bits(l))
            .collect()
    }
}
