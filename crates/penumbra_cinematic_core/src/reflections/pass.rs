//! The reflection pass of one pixel, as the shader (`reflections/trace.wgsl`) computes
//! it: the mirror ray, the nearest billboard hits, each sampled over the GGX lobe's
//! footprint, composited front to back.
//!
//! **Footprint.** Tilting the microfacet normal by a small slope `δ` along the tangent
//! `t` (the view's direction projected on the surface) turns the reflected ray by `2δ`
//! in the plane of incidence; along the bitangent `b`, by `2 (n·v) δ` — why reflections
//! on wet ground stretch toward the viewer. The footprint at distance `s` is the box of
//! half-widths `k α_t s` and `k α_b (n·v) s` across the
//! ray (`k` = [`FOOTPRINT_SLOPE`]), projected along the ray onto the billboard and taken to the
//! image's texels. Its long axis is covered by a few taps ([`sample_footprint`]), each a
//! trilinear sample at the level whose texel spans the tap's width — an explicit
//! anisotropic filter whose result every device computes alike — weighted by the
//! fraction of its box inside the image (soft edges as the lobe widens).
//!
//! **Anisotropy** (`ReflectionUniform::anisotropy`, `a ∈ [0, 0.95]`) stretches the lobe
//! along `t` as Bevy's anisotropic `StandardMaterial` does: `α_t = α (1 + a)`,
//! `α_b = α (1 − a)`.

use encase::ShaderType;
use glam::{IVec2, IVec3, UVec2, Vec2, Vec3, Vec4};

use super::Billboard;
use super::grid::{CasterGrid, GridGather};
use super::texture::MipChain;

/// The footprint's half-width per unit of roughness per metre travelled, `k`. GGX's
/// slopes are heavy-tailed (half of them lie beyond `α`; reflection doubles them), so a
/// box matching the lobe's half-maximum (`2 · 0.766`) is too narrow: 3 is the slope whose
/// box filter is nearest the Monte Carlo truth over perceptual roughness 0–0.5,
/// anisotropic lobes included (`penumbra_reference::reflections`, `footprint_slope_sweep`:
/// summed mean error 0.21 at 3, 0.22–0.23 at 2.5 and 3.5, 0.33 at 1.53, 0.38 at 6).
pub const FOOTPRINT_SLOPE: f32 = 3.0;

/// The most taps along a footprint's long axis.
pub const MAX_TAPS: u32 = 8;

/// Taps along an elongated footprint by default.
pub const DEFAULT_TAPS: u32 = 4;

/// Most anisotropy.
pub const MAX_ANISOTROPY: f32 = 0.95;

/// One billboard as the shader reads it (`penumbra::reflections::trace::GpuBillboard`).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct GpuBillboard {
    /// [`Billboard::center`].
    pub center: Vec3,
    /// Texture array layer of its image.
    pub layer: u32,
    /// [`Billboard::half_x`].
    pub half_x: Vec3,
    /// Multiplies the image's colour: cd/m² for a texel of 1.
    pub emissive: f32,
    /// [`Billboard::half_y`].
    pub half_y: Vec3,
    /// The render-layer groups it belongs to (bit `i`: the scene's `i`-th distinct set of
    /// render layers): a view reflects it where this meets
    /// [`ReflectionUniform::view_layers`]. `u32::MAX`: every view.
    pub layers: u32,
}

impl GpuBillboard {
    /// Whether a view seeing render-layer groups `view_layers` reflects it.
    pub fn seen_by(&self, view_layers: u32) -> bool {
        self.layers & view_layers != 0
    }

    /// Quad `quad` showing image layer `layer` at `emissive` cd/m² per texel of 1.
    pub fn new(quad: &Billboard, layer: u32, emissive: f32) -> Self {
        GpuBillboard {
            center: quad.center,
            layer,
            half_x: quad.half_x,
            emissive,
            half_y: quad.half_y,
            layers: u32::MAX,
        }
    }

    /// The quad.
    pub fn billboard(&self) -> Billboard {
        Billboard {
            center: self.center,
            half_x: self.half_x,
            half_y: self.half_y,
        }
    }
}

/// The reflection pass's settings (`penumbra::reflections::trace::ReflectionUniform`).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct ReflectionUniform {
    /// Billboards in the list.
    pub billboard_count: u32,
    /// Hits composited per pixel, 1..=[`super::MAX_LAYERS`].
    pub max_layers: u32,
    /// Hits farther than this are ignored, metres.
    pub max_distance: f32,
    /// `[0, MAX_ANISOTROPY]`.
    pub anisotropy: f32,
    /// The images' size, texels.
    pub texture_size: UVec2,
    /// Levels in the texture array.
    pub mip_count: u32,
    /// 1: the pass runs at half resolution (each texel shades the top-left pixel of its
    /// 2 × 2 block).
    pub half_resolution: u32,
    /// The camera's tile (the distance-field scene's camera-relative frame).
    pub camera_tile: IVec3,
    /// Slots of the distance-field object buffer to march (0: no reflection shadows).
    pub object_count: u32,
    /// The camera's position within its tile, metres.
    pub camera_offset: Vec3,
    /// The footprint's half-width per unit of roughness per metre ([`FOOTPRINT_SLOPE`]).
    pub footprint_slope: f32,
    /// Reflection shadows' march steps (0: off).
    pub shadow_steps: u32,
    /// Where the march starts along the ray, metres.
    pub shadow_bias: f32,
    /// The narrowest shadow cone's half-angle tangent (a mirror's shadows stay this soft).
    pub shadow_softness: f32,
    /// Taps along an elongated footprint, 1..=[`MAX_TAPS`] ([`sample_footprint`]).
    pub taps: u32,
    /// Tiles ([`super::cull::TILE`] pixels square) per row of the trace's image.
    pub tiles_x: u32,
    /// Billboards a tile's list holds (0: no tile lists; the trace tests every
    /// billboard).
    pub tile_capacity: u32,
    /// The trace's image size, pixels.
    pub trace_size: UVec2,
    /// The shadow cone's half-width as a share of the footprint's long half-axis
    /// ([`SHADOW_CONE`]).
    pub shadow_cone: f32,
    /// Shadow casters a tile's list holds (0: no caster lists; each pixel's march
    /// gathers from every object).
    pub caster_capacity: u32,
    /// The render-layer groups the view sees ([`GpuBillboard::layers`]); a billboard
    /// sharing none is neither listed nor traced.
    pub view_layers: u32,
    /// Where the caster grid ([`super::grid`]) starts in the view's list buffer, words
    /// (0: no grid; a tile whose caster list overflows gathers from every object).
    pub caster_grid: u32,
}

impl ReflectionUniform {
    /// The settings with no reflection shadows, the camera at the origin.
    pub fn new(billboard_count: u32, texture_size: UVec2, mip_count: u32) -> Self {
        ReflectionUniform {
            billboard_count,
            max_layers: super::DEFAULT_LAYERS as u32,
            max_distance: 100.0,
            anisotropy: 0.0,
            texture_size,
            mip_count,
            half_resolution: 0,
            camera_tile: IVec3::ZERO,
            object_count: 0,
            camera_offset: Vec3::ZERO,
            footprint_slope: FOOTPRINT_SLOPE,
            shadow_steps: 0,
            shadow_bias: DEFAULT_SHADOW_BIAS,
            shadow_softness: DEFAULT_SHADOW_SOFTNESS,
            taps: DEFAULT_TAPS,
            tiles_x: 0,
            tile_capacity: 0,
            trace_size: UVec2::ZERO,
            shadow_cone: SHADOW_CONE,
            caster_capacity: 0,
            view_layers: u32::MAX,
            caster_grid: 0,
        }
    }
}

/// Where reflection shadows' march starts by default, metres.
pub const DEFAULT_SHADOW_BIAS: f32 = 0.02;
/// The narrowest shadow cone by default (tangent of its half-angle).
pub const DEFAULT_SHADOW_SOFTNESS: f32 = 0.02;
/// The reflection-shadow cone's half-width as a share of the footprint's long
/// half-axis. The cone test (`d / (cone t)`) takes the nearest surface as covering the
/// whole cone, too dark for thin occluders in wide lobes: against exact visibility
/// (`penumbra_reference::reflections` figures, `shadow_cone_sweep`: a wall and a row of
/// posts, perceptual roughness 0, 0.3, 0.5) the summed mean error is 0.278 at 1/8, 0.280
/// at 1/4, 0.291 at 1/2 and 0.324 at the full footprint.
pub const SHADOW_CONE: f32 = 0.125;

/// The shortest march step, metres.
pub const MIN_SHADOW_STEP: f32 = 0.01;

/// A G-buffer sample as the pass sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// World position, metres.
    pub position: Vec3,
    /// Unit world normal.
    pub normal: Vec3,
    /// Unit vector from the surface toward the eye.
    pub view: Vec3,
    /// Bevy's perceptual roughness.
    pub perceptual_roughness: f32,
}

/// Bevy's roughness from perceptual roughness (`perceptualRoughnessToRoughness`: clamped
/// to at least 0.089 first).
pub fn roughness(perceptual_roughness: f32) -> f32 {
    let p = perceptual_roughness.clamp(0.089, 1.0);
    p * p
}

/// The mirror ray and the lobe's footprint axes per metre travelled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobe {
    /// The mirror direction.
    pub dir: Vec3,
    /// Across the ray in the plane of incidence, scaled to the footprint's half-width
    /// per metre.
    pub major: Vec3,
    /// Across the ray along the bitangent, scaled likewise.
    pub minor: Vec3,
}

/// The lobe of a surface sample under `anisotropy`, its footprint `slope` (half-width per
/// unit of roughness per metre, [`FOOTPRINT_SLOPE`]).
pub fn lobe(s: &Surface, anisotropy: f32, slope: f32) -> Lobe {
    let n = s.normal;
    let n_dot_v = n.dot(s.view).max(1e-4);
    let dir = 2.0 * n_dot_v * n - s.view;
    let along = s.view - n * n.dot(s.view);
    // Straight down the normal: any tangent (the footprint is round there).
    let t = if along.length_squared() > 1e-8 {
        along.normalize()
    } else {
        any_perpendicular(n)
    };
    let b = n.cross(t);
    let e1 = n_dot_v * t + s.view.dot(t) * n;
    let alpha = roughness(s.perceptual_roughness);
    let a = anisotropy.clamp(0.0, MAX_ANISOTROPY);
    Lobe {
        dir,
        major: e1 * (slope * alpha * (1.0 + a)),
        minor: b * (slope * alpha * (1.0 - a) * n_dot_v),
    }
}

/// A unit vector perpendicular to unit `n` (Duff et al.'s branchless basis).
pub fn any_perpendicular(n: Vec3) -> Vec3 {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x)
}

/// One accepted hit: where, and the footprint's axes in image coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootprintHit {
    /// Distance along the ray, metres.
    pub t: f32,
    /// The billboard's index.
    pub index: u32,
    /// Image coordinates of the mirror hit (may lie outside `[0, 1]` by the footprint).
    pub uv: Vec2,
    /// The footprint's half-axes in image coordinates.
    pub axis_a: Vec2,
    /// The other half-axis.
    pub axis_b: Vec2,
}

/// The hit of `lobe` from `origin` on `b` (front side, `0 < t ≤ max_distance`) whose
/// footprint overlaps the image.
pub fn footprint_hit(
    b: &Billboard,
    index: u32,
    origin: Vec3,
    lobe: &Lobe,
    max_distance: f32,
) -> Option<FootprintHit> {
    let n = b.half_x.cross(b.half_y);
    let facing = lobe.dir.dot(n);
    if facing.is_nan() || facing >= 0.0 {
        return None;
    }
    let t = (b.center - origin).dot(n) / facing;
    if t.is_nan() || t <= 0.0 || t > max_distance {
        return None;
    }
    let n2 = n.length_squared();
    let du = b.half_y.cross(n) * (0.5 / n2);
    let dv = n.cross(b.half_x) * (-0.5 / n2);
    let to_uv = |p: Vec3| Vec2::new(p.dot(du), p.dot(dv));
    // Offsets across the ray, projected along it onto the plane.
    let project = |o: Vec3| o - lobe.dir * (o.dot(n) / facing);
    let p = origin + lobe.dir * t - b.center;
    let uv = to_uv(p) + 0.5;
    let axis_a = to_uv(project(lobe.major * t));
    let axis_b = to_uv(project(lobe.minor * t));
    let reach = axis_a.abs() + axis_b.abs();
    let inside = uv.cmpge(-reach).all() && uv.cmple(Vec2::ONE + reach).all();
    inside.then_some(FootprintHit {
        t,
        index,
        uv,
        axis_a,
        axis_b,
    })
}

/// The fraction of the box `[c − e, c + e]` inside `[0, 1]` (1 for a point inside).
pub fn box_coverage(c: f32, e: f32) -> f32 {
    if e <= 1e-7 {
        return if (0.0..=1.0).contains(&c) { 1.0 } else { 0.0 };
    }
    (((c + e).clamp(0.0, 1.0) - (c - e).clamp(0.0, 1.0)) / (2.0 * e)).min(1.0)
}

/// The premultiplied image over a hit's footprint: `taps` trilinear samples (at most
/// [`MAX_TAPS`]) along its long axis — one where the footprint is round — each of
/// half-length `h = max(short, long / taps)` at the level whose texel spans `2h`, their
/// centres spread evenly over `±(long − h)`. Everything varies continuously with the
/// footprint's shape (a tap count chosen per pixel from its elongation would jump, and
/// draw contour lines across a glossy streak).
pub fn sample_footprint(image: &MipChain, hit: &FootprintHit, taps: u32) -> Vec4 {
    let size = Vec2::new(image.width as f32, image.height as f32);
    let (ta, tb) = (hit.axis_a * size, hit.axis_b * size);
    let (long, short, long_uv, short_uv) = if ta.length() >= tb.length() {
        (ta.length(), tb.length(), hit.axis_a, hit.axis_b)
    } else {
        (tb.length(), ta.length(), hit.axis_b, hit.axis_a)
    };
    let taps = if long > short * 1.0001 {
        taps.clamp(1, MAX_TAPS)
    } else {
        1
    };
    let n = taps as f32;
    let half = short.max(long / n);
    let lod = (2.0 * half).max(1.0).log2();
    // The share of the long axis one tap covers, and the spread of the tap centres.
    let share = if long > 0.0 { half / long } else { 1.0 };
    let reach = short_uv.abs() + long_uv.abs() * share;
    let mut sum = Vec4::ZERO;
    for k in 0..taps {
        let at = if taps > 1 {
            2.0 * k as f32 / (n - 1.0) - 1.0
        } else {
            0.0
        };
        let uv = hit.uv + long_uv * ((1.0 - share) * at);
        let cover = box_coverage(uv.x, reach.x) * box_coverage(uv.y, reach.y);
        if cover > 0.0 {
            sum += image.sample(uv, lod) * cover;
        }
    }
    sum / n
}

/// The billboards' reflection in one pixel: premultiplied radiance (cd/m², the
/// billboards' emissive applied) and coverage, `1 −` what is left of the light behind.
/// `images[layer]` is each layer's chain. No reflection shadows.
pub fn reflect_pixel(
    s: &Surface,
    billboards: &[GpuBillboard],
    images: &[MipChain],
    settings: &ReflectionUniform,
) -> Vec4 {
    let none = ShadowCasters {
        spheres: &[],
        distance: |_, _| f32::MAX,
    };
    reflect_pixel_shadowed(s, billboards, images, settings, &none)
}

/// The shadow-casting objects the reflection shadows march through: each object's
/// bounding sphere (world centre and radius, metres; `None`: unbounded) and its distance
/// at a world point.
pub struct ShadowCasters<'a, F: Fn(usize, Vec3) -> f32> {
    /// Per object, its bounding sphere.
    pub spheres: &'a [Option<(Vec3, f32)>],
    /// Object `i`'s distance (metres) at a world point.
    pub distance: F,
}

/// Most objects one pixel's march keeps after its cull; more: it marches them all.
pub const MAX_SHADOW_CASTERS: usize = 32;

/// Slack added to a cull's reach (rounding must never drop an object): as the
/// distance-field passes' `cull_slack`.
fn cull_slack(reach: f32) -> f32 {
    reach * 1e-4 + 1e-4
}

/// The march's ray is split into this many equal segments, each with the objects near
/// it ([`shadow_casters`]): a long ray across a crowded scene keeps few per segment.
pub const SHADOW_SEGMENTS: usize = 8;

/// Where each of the [`SHADOW_SEGMENTS`] segments of a march to `t_end` ends: `t_end ·
/// (k + 1) / 8` (exact in `f32`: the shader computes the same bits).
pub fn segment_ends(t_end: f32) -> [f32; SHADOW_SEGMENTS] {
    std::array::from_fn(|k| t_end * (0.125 * (k + 1) as f32))
}

/// The objects a pixel's reflection-shadow march may see between `t0` and `t1` along
/// its ray (`reflections/trace.wgsl`'s `gather_casters`): those of `candidates` (the
/// tile's caster list; `None`: every object) whose bounding sphere comes within
/// `cone · t1` of that segment — farther, an object's distance is at least the cone's
/// radius `cone · t` at every step there, so it never dims a hit. `None`: more than
/// [`MAX_SHADOW_CASTERS`]: march every candidate there.
pub fn shadow_casters(
    spheres: &[Option<(Vec3, f32)>],
    candidates: Option<&[usize]>,
    origin: Vec3,
    dir: Vec3,
    t0: f32,
    t1: f32,
    cone: f32,
) -> Option<Vec<usize>> {
    let start = origin + dir * t0;
    let end = origin + dir * t1;
    let mut kept = Vec::new();
    for i in candidate_indices(candidates, spheres.len()) {
        if keeps_caster(spheres[i], start, end, cone * t1) {
            if kept.len() == MAX_SHADOW_CASTERS {
                return None;
            }
            kept.push(i);
        }
    }
    Some(kept)
}

/// Whether a gather of the segment `a`–`b` keeps the object of bounding `sphere`
/// (`None`: unbounded, always kept): its sphere comes within `reach` (the cone's
/// `cone · t1`) of the segment (`reflections/trace.wgsl`'s `keeps_caster`).
pub fn keeps_caster(sphere: Option<(Vec3, f32)>, a: Vec3, b: Vec3, reach: f32) -> bool {
    sphere.is_none_or(|(center, radius)| {
        let reach = radius + reach;
        segment_distance(center, a, b) < reach + cull_slack(reach)
    })
}

/// The tile's caster list, or every object's index below `count`.
fn candidate_indices(
    candidates: Option<&[usize]>,
    count: usize,
) -> impl Iterator<Item = usize> + '_ {
    let listed = candidates.map(|list| list.iter().copied());
    let every = candidates.is_none().then_some(0..count);
    listed
        .into_iter()
        .flatten()
        .chain(every.into_iter().flatten())
}

/// The distance from `p` to the segment `a`–`b`.
fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let l2 = ab.dot(ab);
    let h = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - a - ab * h).length()
}

/// [`reflect_pixel`] with reflection shadows (when `settings.shadow_steps > 0`): each
/// hit's radiance scaled by its visibility along the mirror ray ([`shadow_march`])
/// through `casters` — those [`shadow_casters`] keeps for the pixel's ray, up to its last
/// hit.
pub fn reflect_pixel_shadowed<F: Fn(usize, Vec3) -> f32>(
    s: &Surface,
    billboards: &[GpuBillboard],
    images: &[MipChain],
    settings: &ReflectionUniform,
    casters: &ShadowCasters<'_, F>,
) -> Vec4 {
    reflect_pixel_in_tile(s, billboards, images, settings, casters, None)
}

/// [`reflect_pixel_shadowed`] for a pixel whose tile lists its shadow casters
/// (`tile_casters`, from [`super::cull::tile_casters`]; `None`: the tile has no list):
/// the march gathers from that list, and a segment with more than
/// [`MAX_SHADOW_CASTERS`] marches the list rather than every object. The gathered
/// segments are the same (the tile's list holds every object they can keep); an
/// overflowing segment's steps may differ in length, by objects too far to dim a hit.
pub fn reflect_pixel_in_tile<F: Fn(usize, Vec3) -> f32>(
    s: &Surface,
    billboards: &[GpuBillboard],
    images: &[MipChain],
    settings: &ReflectionUniform,
    casters: &ShadowCasters<'_, F>,
    tile_casters: Option<&[usize]>,
) -> Vec4 {
    let from = tile_casters.map_or(Gather::Every, Gather::Tile);
    reflect_pixel_gathered(s, billboards, images, settings, casters, from)
}

/// Where a pixel's shadow march gathers each segment's casters from.
#[derive(Clone, Copy, Debug)]
pub enum Gather<'a> {
    /// Every object.
    Every,
    /// Its tile's caster list ([`super::cull::tile_casters`]).
    Tile(&'a [usize]),
    /// The caster grid (a tile whose list overflowed): the same objects as
    /// [`Gather::Every`], found in the cells near each segment.
    Grid(&'a CasterGrid),
    /// The caster grid for a tile with a long list: the same objects as
    /// [`Gather::Tile`] (the list holds every object its segments can keep); a segment
    /// gathering too many marches the list.
    TileGrid(&'a [usize], &'a CasterGrid),
}

impl<'a> Gather<'a> {
    /// Where the shader gathers a pixel's casters from: its tile's list (`None`: the
    /// list overflowed), or the grid where there is one and the list is missing or
    /// longer than [`super::grid::GRID_OVER_LIST`].
    pub fn for_tile(list: Option<&'a [usize]>, grid: Option<&'a CasterGrid>) -> Self {
        match (list, grid) {
            (None, None) => Gather::Every,
            (None, Some(grid)) => Gather::Grid(grid),
            (Some(list), Some(grid)) if list.len() > super::grid::GRID_OVER_LIST => {
                Gather::TileGrid(list, grid)
            }
            (Some(list), _) => Gather::Tile(list),
        }
    }
}

/// [`reflect_pixel_in_tile`] with the segments' casters gathered `from` a tile's list,
/// the caster grid or every object (`reflections/trace.wgsl`'s `gather_casters`).
pub fn reflect_pixel_gathered<F: Fn(usize, Vec3) -> f32>(
    s: &Surface,
    billboards: &[GpuBillboard],
    images: &[MipChain],
    settings: &ReflectionUniform,
    casters: &ShadowCasters<'_, F>,
    from: Gather<'_>,
) -> Vec4 {
    let (tile_casters, grid) = match from {
        Gather::Every => (None, None),
        Gather::Tile(list) => (Some(list), None),
        Gather::Grid(grid) => (None, Some(grid)),
        Gather::TileGrid(list, grid) => (Some(list), Some(grid)),
    };
    let lobe = lobe(s, settings.anisotropy, settings.footprint_slope);
    let k = settings.max_layers.clamp(1, super::MAX_LAYERS as u32) as usize;
    let mut hits: Vec<FootprintHit> = Vec::with_capacity(k + 1);
    for (index, gpu) in billboards.iter().enumerate() {
        if !gpu.seen_by(settings.view_layers) {
            continue;
        }
        let Some(hit) = footprint_hit(
            &gpu.billboard(),
            index as u32,
            s.position,
            &lobe,
            settings.max_distance,
        ) else {
            continue;
        };
        let at = hits
            .iter()
            .position(|h| (hit.t, hit.index) < (h.t, h.index))
            .unwrap_or(hits.len());
        if at < k {
            hits.insert(at, hit);
            hits.truncate(k);
        }
    }
    let targets: Vec<ShadowTarget> = hits
        .iter()
        .map(|h| ShadowTarget {
            t: h.t,
            facing: lobe
                .dir
                .dot(billboards[h.index as usize].billboard().normal())
                .abs(),
        })
        .collect();
    let cone = (lobe.major.length() * settings.shadow_cone).max(settings.shadow_softness);
    let ends = segment_ends(targets.last().map_or(0.0, |h| h.t));
    // Each segment's objects, gathered when the march first reaches it.
    let mut gathered: [Option<Option<Vec<usize>>>; SHADOW_SEGMENTS] = Default::default();
    let scene_distance = |k: usize, p: Vec3| {
        let kept = gathered[k].get_or_insert_with(|| {
            let t0 = if k == 0 { 0.0 } else { ends[k - 1] };
            if let Some(grid) = grid {
                match grid.gather(casters.spheres, s.position, lobe.dir, t0, ends[k], cone) {
                    GridGather::Kept(kept) => return Some(kept),
                    GridGather::Overflow => return None,
                    GridGather::TooWide => {}
                }
            }
            shadow_casters(
                casters.spheres,
                tile_casters,
                s.position,
                lobe.dir,
                t0,
                ends[k],
                cone,
            )
        });
        let distance = |i: usize| (casters.distance)(i, p);
        match kept {
            Some(kept) => kept.iter().map(|&i| distance(i)).fold(f32::MAX, f32::min),
            None => candidate_indices(tile_casters, casters.spheres.len())
                .map(distance)
                .fold(f32::MAX, f32::min),
        }
    };
    let visibility = march_segments(
        s.position,
        lobe.dir,
        &targets,
        cone,
        settings,
        &ends,
        scene_distance,
    );
    let (mut colour, mut transmittance) = (Vec3::ZERO, 1.0f32);
    for (hit, v) in hits.iter().zip(visibility) {
        let gpu = &billboards[hit.index as usize];
        let texel = sample_footprint(&images[gpu.layer as usize], hit, settings.taps);
        colour += transmittance * texel.truncate() * (gpu.emissive * v);
        transmittance *= 1.0 - texel.w.clamp(0.0, 1.0);
    }
    colour
        .min(Vec3::splat(MAX_REFLECTED_RADIANCE))
        .extend(1.0 - transmittance)
}

/// The most a reflection layer holds per channel: its `Rgba16Float` texels' largest
/// finite value (a billboard's `emissive` above it overflowed to infinity, and then to
/// NaN in the composite, #47). `reflections/trace.wgsl`'s `reflect_billboards`.
pub const MAX_REFLECTED_RADIANCE: f32 = 65504.0;

/// Where a reflected ray meets a billboard, as the shadow march sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowTarget {
    /// Distance along the ray, metres.
    pub t: f32,
    /// `|dir · n|`, the ray against the billboard's unit normal: a point at `s` along
    /// the ray is `(t − s) · facing` from the billboard's plane.
    pub facing: f32,
}

/// Reflection shadows: the visibility of each target in `hits` (ascending) along the ray
/// `origin + t dir`, from one sphere-traced march through the scene's distance field —
/// from `shadow_bias` on, steps of `max(d, MIN_SHADOW_STEP)`, at most `shadow_steps` —
/// keeping the running minimum of `d / (cone · t)` (a cone of half-angle tangent `cone`:
/// shadows soften with the distance travelled). A sample counts only when `d` is less
/// than its distance to the next target's plane: then the surface it found lies in
/// front of that billboard, between it and the reflecting point; otherwise it may lie
/// behind the billboard (the wall a sign hangs on), which hides nothing. A target the
/// march does not reach in its steps keeps the visibility found so far. All 1 when
/// `shadow_steps` is 0.
pub fn shadow_march(
    origin: Vec3,
    dir: Vec3,
    hits: &[ShadowTarget],
    cone: f32,
    settings: &ReflectionUniform,
    scene_distance: impl Fn(Vec3) -> f32,
) -> [f32; super::MAX_LAYERS] {
    march_segments(
        origin,
        dir,
        hits,
        cone,
        settings,
        &[f32::INFINITY],
        |_, p| scene_distance(p),
    )
}

/// [`shadow_march`] with the ray in segments ending at `ends` (ascending; the last one
/// past the last hit): the distance at a step is `scene_distance(k, p)` in segment `k`,
/// and a step that would cross a segment's end stops on it, so the next segment's
/// objects are seen from its start (`reflections/trace.wgsl`'s `shadow_march`).
pub fn march_segments(
    origin: Vec3,
    dir: Vec3,
    hits: &[ShadowTarget],
    cone: f32,
    settings: &ReflectionUniform,
    ends: &[f32],
    mut scene_distance: impl FnMut(usize, Vec3) -> f32,
) -> [f32; super::MAX_LAYERS] {
    let mut out = [1.0f32; super::MAX_LAYERS];
    if settings.shadow_steps == 0 || settings.object_count == 0 || ends.is_empty() {
        return out;
    }
    let (mut t, mut v, mut j, mut k) = (settings.shadow_bias, 1.0f32, 0usize, 0usize);
    let n = hits.len().min(super::MAX_LAYERS);
    let last = ends.len() - 1;
    for _ in 0..settings.shadow_steps {
        while j < n && t >= hits[j].t {
            out[j] = v;
            j += 1;
        }
        if j >= n || v <= 0.0 {
            break;
        }
        while k < last && t >= ends[k] {
            k += 1;
        }
        let d = scene_distance(k, origin + dir * t);
        if d < (hits[j].t - t) * hits[j].facing {
            v = v.min((d / (cone * t)).clamp(0.0, 1.0));
        }
        let next = t + d.max(MIN_SHADOW_STEP);
        t = if k < last && next > ends[k] {
            ends[k]
        } else {
            next
        };
    }
    for slot in out.iter_mut().take(n).skip(j) {
        *slot = v;
    }
    out
}

/// The lighting pass's read of a half-resolution layer at full-resolution `pixel` of
/// view depth `view_z` (`lighting/lights.wgsl`'s `specular_layer_at`): texel `i` holds
/// pixel `2i`; the (up to) four texels around the pixel, bilinearly weighted, keep those
/// whose pixel's view depth (`texel_view_z`) is within 10 % of the pixel's; the nearest
/// in depth when none is. `half_size`: the layer's size.
pub fn upsample_half(
    texel: impl Fn(IVec2) -> Vec4,
    texel_view_z: impl Fn(IVec2) -> f32,
    half_size: IVec2,
    pixel: IVec2,
    view_z: f32,
) -> Vec4 {
    let base = pixel / 2;
    let odd = (pixel - base * 2).as_vec2() * 0.5;
    let (mut sum, mut weight) = (Vec4::ZERO, 0.0f32);
    let (mut nearest, mut nearest_gap) = (Vec4::ZERO, f32::MAX);
    for k in 0..4 {
        let offset = IVec2::new(k & 1, k >> 1);
        let at = (base + offset).min(half_size - 1);
        let bx = if offset.x == 0 { 1.0 - odd.x } else { odd.x };
        let by = if offset.y == 0 { 1.0 - odd.y } else { odd.y };
        let bilinear = bx * by;
        if bilinear == 0.0 {
            continue;
        }
        let value = texel(at);
        let gap = (texel_view_z(at * 2) - view_z).abs();
        if gap <= 0.1 * view_z.abs() {
            sum += value * bilinear;
            weight += bilinear;
        }
        if gap < nearest_gap {
            nearest_gap = gap;
            nearest = value;
        }
    }
    if weight > 0.0 { sum / weight } else { nearest }
}

#[cfg(test)]
mod tests;
