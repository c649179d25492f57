//! The scatter bokeh passes: [`downsample`] to half resolution, [`sprites`] (one or
//! four per 2×2 block), [`scatter_sprites`] into the near and far layers (half
//! resolution, quarter resolution for large sprites), [`composite`] at full resolution;
//! [`depth_of_field`] runs them in order.
//!
//! Units: circles of confusion are signed diameters in **full-resolution** pixels
//! (negative in front of the focal plane); sprite positions and sizes are in
//! half-resolution pixels, `(0, 0)` the top-left corner of the half image.

use super::{Aperture, HALF_RES_BLUR, Lens, QUARTER_RES_BLUR, SpriteRule};
use glam::{UVec2, Vec2, Vec3, Vec4};

/// A linear HDR image and the distance along the view axis of each pixel (metres;
/// `f32::INFINITY` for the sky), rows from the top.
#[derive(Clone, Debug)]
pub struct BokehImage {
    /// Pixels across and down.
    pub size: UVec2,
    /// Linear colour per pixel.
    pub color: Vec<Vec3>,
    /// Distance along the view axis per pixel, metres.
    pub distance: Vec<f32>,
}

/// The half-resolution copy the sprites are made from.
#[derive(Clone, Debug)]
pub struct HalfImage {
    /// `ceil(full / 2)`.
    pub size: UVec2,
    /// Mean colour of the 2×2 full-resolution pixels.
    pub color: Vec<Vec3>,
    /// Circle of confusion of the nearest of them (full-resolution pixels, signed).
    pub coc: Vec<f32>,
    /// Distance of the nearest of them, at most `Lens::max_depth` and `f32::MAX`.
    pub distance: Vec<f32>,
}

/// One textured quad of the scatter pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sprite {
    /// Centre, half-resolution pixels.
    pub center: Vec2,
    /// Width and height of the aperture's image, half-resolution pixels (the quad is
    /// one pixel wider for a block).
    pub diameter: f32,
    /// The colour it spreads: the sum over the pixels it stands for.
    pub color: Vec3,
    /// How many half-resolution pixels it stands for: 1, 4 for a 2×2 block or 16 for a
    /// 4×4 group, whose quad adds the aperture at each of its pixel centres (the sprites
    /// it replaces, drawn as one quad with a quarter or a sixteenth of the blending).
    pub weight: f32,
    /// In front of the focal plane (the near layer), or behind it.
    pub near: bool,
}

impl Sprite {
    /// Texels across the square it stands for: 1, 2 for a block, 4 for a group.
    pub fn side(&self) -> u32 {
        if self.weight > 4.0 {
            4
        } else if self.weight > 1.0 {
            2
        } else {
            1
        }
    }

    /// How far apart its outermost texel centres are, half-resolution pixels: its quad
    /// is this much wider than the aperture.
    pub fn spread(&self) -> f32 {
        (self.side() - 1) as f32
    }
}

/// The scatter pass's targets: `(Σ colour, Σ weight)` per texel, a near and a far layer
/// at half resolution and at quarter resolution (sprites at least
/// [`SpriteRule::quarter_diameter`] wide). A quarter texel covers four half texels: the
/// composite adds a quarter of its value to the half layer's.
#[derive(Clone, Debug)]
pub struct Layers {
    /// Half-resolution size.
    pub size: UVec2,
    /// In front of the focal plane.
    pub near: Vec<Vec4>,
    /// Behind it.
    pub far: Vec<Vec4>,
    /// Quarter-resolution size, `ceil(size / 2)`.
    pub quarter_size: UVec2,
    /// In front of the focal plane, quarter resolution.
    pub near_quarter: Vec<Vec4>,
    /// Behind it, quarter resolution.
    pub far_quarter: Vec<Vec4>,
}

/// The largest finite `f16`: what the sprites and the composite take of a brighter (or
/// infinite) pixel of the HDR target (`dof/types.wgsl`'s `scene_color`).
pub const MAX_SCENE_COLOR: f32 = 65504.0;

/// A pixel of the HDR target as the sprites take it: each channel at most
/// [`MAX_SCENE_COLOR`], NaN as 0 — one +Inf pixel (above an `Rgba16Float` target's
/// range) made its sprite, and the whole square it covers, NaN (#47).
pub fn scene_color(c: Vec3) -> Vec3 {
    Vec3::from_array(c.to_array().map(|v| {
        if v.is_nan() {
            0.0
        } else {
            v.min(MAX_SCENE_COLOR)
        }
    }))
}

/// Half-resolution colour (mean of each 2×2 block, edge pixels repeated) and the
/// circle of confusion and distance of the block's nearest pixel, so a near object's
/// blur is not diluted at its silhouette.
pub fn downsample(image: &BokehImage, lens: &Lens) -> HalfImage {
    let full = image.size;
    let size = (full + UVec2::ONE) / 2;
    let mut half = HalfImage {
        size,
        color: Vec::with_capacity((size.x * size.y) as usize),
        coc: Vec::with_capacity((size.x * size.y) as usize),
        distance: Vec::with_capacity((size.x * size.y) as usize),
    };
    for y in 0..size.y {
        for x in 0..size.x {
            let (mut color, mut nearest) = (Vec3::ZERO, f32::INFINITY);
            let mut first = true;
            for k in 0..4u32 {
                let p = (UVec2::new(2 * x + (k & 1), 2 * y + (k >> 1))).min(full - UVec2::ONE);
                let i = (p.y * full.x + p.x) as usize;
                color += scene_color(image.color[i]);
                // The sky (and NaN) at `max_depth`, finite as on the GPU.
                let d = image.distance[i];
                let d = if d.is_nan() {
                    f32::MAX
                } else {
                    d.min(lens.max_depth).min(f32::MAX)
                };
                if first || d < nearest {
                    nearest = d;
                    first = false;
                }
            }
            half.color.push(color / 4.0);
            half.coc.push(lens.coc(nearest, full.y));
            half.distance.push(nearest);
        }
    }
    half
}

fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// What the 1-or-4 rule reads of a 2×2 block of half-resolution texels, or of a 2×2
/// group of blocks ([`GroupStats::of_blocks`]), accumulated in the sprite pass's order.
#[derive(Clone, Copy, Debug, PartialEq)]
struct GroupStats {
    coc_lo: f32,
    coc_hi: f32,
    /// Σ circle of confusion.
    coc_sum: f32,
    l_lo: f32,
    l_hi: f32,
    /// Mean luminance, summed as Σ (l / n).
    l_mean: f32,
    d_lo: f32,
    d_hi: f32,
    /// Mean distance, summed as Σ (d / n) (four `f32::MAX` skies do not overflow).
    d_mean: f32,
    /// Σ colour.
    color: Vec3,
    /// Texels it stands for: 4 or 16.
    texels: f32,
}

impl GroupStats {
    /// A block's four texels (colour, circle of confusion, distance).
    fn of_texels(texels: &[(Vec3, f32, f32); 4]) -> Self {
        let mut g = GroupStats {
            coc_lo: texels[0].1,
            coc_hi: texels[0].1,
            coc_sum: 0.0,
            l_lo: luminance(texels[0].0),
            l_hi: luminance(texels[0].0),
            l_mean: 0.0,
            d_lo: texels[0].2,
            d_hi: texels[0].2,
            d_mean: 0.0,
            color: Vec3::ZERO,
            texels: 4.0,
        };
        for &(color, coc, distance) in texels {
            let l = luminance(color);
            g.coc_lo = g.coc_lo.min(coc);
            g.coc_hi = g.coc_hi.max(coc);
            g.coc_sum += coc;
            g.l_lo = g.l_lo.min(l);
            g.l_hi = g.l_hi.max(l);
            g.l_mean += l / 4.0;
            g.d_lo = g.d_lo.min(distance);
            g.d_hi = g.d_hi.max(distance);
            g.d_mean += distance / 4.0;
            g.color += color;
        }
        g
    }

    /// Four blocks (row-major) as one 4×4 group.
    fn of_blocks(blocks: &[GroupStats; 4]) -> Self {
        let mut g = GroupStats {
            coc_sum: 0.0,
            l_mean: 0.0,
            d_mean: 0.0,
            color: Vec3::ZERO,
            texels: 16.0,
            ..blocks[0]
        };
        for b in blocks {
            g.coc_lo = g.coc_lo.min(b.coc_lo);
            g.coc_hi = g.coc_hi.max(b.coc_hi);
            g.coc_sum += b.coc_sum;
            g.l_lo = g.l_lo.min(b.l_lo);
            g.l_hi = g.l_hi.max(b.l_hi);
            g.l_mean += b.l_mean / 4.0;
            g.d_lo = g.d_lo.min(b.d_lo);
            g.d_hi = g.d_hi.max(b.d_hi);
            g.d_mean += b.d_mean / 4.0;
            g.color += b.color;
        }
        g
    }

    /// The mean circle of confusion.
    fn coc(&self) -> f32 {
        self.coc_sum / self.texels
    }

    /// Whether its texels may be one sprite: all out of focus on one side of the focal
    /// plane, their circles of confusion, luminance and distances within the rule's
    /// tolerances.
    fn agrees(&self, rule: &SpriteRule) -> bool {
        let same_side = self.coc_lo > 0.0 || self.coc_hi < 0.0;
        let in_focus = self.coc_lo.abs().min(self.coc_hi.abs()) < rule.min_coc.max(1e-3);
        same_side
            && !in_focus
            && self.coc_hi - self.coc_lo <= rule.coc_tolerance
            && self.l_hi - self.l_lo <= rule.color_tolerance * self.l_mean.max(1e-4)
            && (self.d_hi - self.d_lo <= rule.depth_tolerance * self.d_mean
                || self.d_lo == self.d_hi)
    }

    /// The one sprite its texels make, centred at `center`.
    fn sprite(&self, center: Vec2) -> Sprite {
        let coc = self.coc();
        Sprite {
            center,
            diameter: sprite_diameter(coc),
            color: self.color,
            weight: self.texels,
            near: coc < 0.0,
        }
    }
}

/// The half-resolution diameter of the aperture image for a circle of confusion of
/// `coc` full-resolution pixels: below 8 px, where the half-resolution blur is a large
/// part of the result, `√(coc² − HALF_RES_BLUR)` so that the result's spread matches
/// (the thin-lens check's out-of-focus error falls from 0.0093 to 0.0042); from 16 px
/// `coc` itself, so large bokeh keep their edges where the shape puts them; in between
/// the correction fades. At least one half-resolution pixel.
pub fn sprite_diameter(coc: f32) -> f32 {
    let d = coc.abs();
    let fade = ((16.0 - d) / 8.0).clamp(0.0, 1.0);
    (0.5 * (d * d - HALF_RES_BLUR * fade).max(0.0).sqrt()).max(1.0)
}

/// The sprites of `half`: per 2×2 block of texels, one sprite at the block's centre
/// (the mean circle of confusion, carrying the four colours) when `rule.merge` and all
/// four are out of focus on the same side and agree; otherwise one per texel whose
/// circle of confusion reaches `rule.min_coc`. Where a 2×2 group of blocks (blocks
/// `2i, 2i + 1` across and down) agrees as a whole and its sprite is drawn at half
/// resolution, that one sprite stands for its sixteen texels, in its first block's
/// place. In block order, then texel order within the block (the GPU's order differs;
/// the sum does not).
pub fn sprites(half: &HalfImage, rule: &SpriteRule) -> Vec<Sprite> {
    let size = half.size;
    let blocks = (size + UVec2::ONE) / 2;
    let min_coc = rule.min_coc.max(1e-3);
    let texel = |b: UVec2, k: u32| 2 * b + UVec2::new(k & 1, k >> 1);
    let inside = |b: UVec2| (0..4).all(|k| texel(b, k).cmplt(size).all());
    let value = |p: UVec2| {
        let i = (p.y * size.x + p.x) as usize;
        (half.color[i], half.coc[i], half.distance[i])
    };
    let stats = |b: UVec2| GroupStats::of_texels(&[0, 1, 2, 3].map(|k| value(texel(b, k))));
    let mut grouped = vec![false; (blocks.x * blocks.y) as usize];
    let mut out = Vec::new();
    for by in 0..blocks.y {
        for bx in 0..blocks.x {
            let block = UVec2::new(bx, by);
            if grouped[(by * blocks.x + bx) as usize] {
                continue;
            }
            if rule.merge && rule.merge_groups && bx % 2 == 0 && by % 2 == 0 {
                let members = [0, 1, 2, 3].map(|k| block + UVec2::new(k & 1, k >> 1));
                if members.iter().all(|&b| b.cmplt(blocks).all() && inside(b)) {
                    let group = GroupStats::of_blocks(&members.map(stats));
                    let sprite = group.sprite((2 * block).as_vec2() + 2.0);
                    if group.agrees(rule) && !is_quarter(&sprite, rule.quarter_diameter()) {
                        for b in members {
                            grouped[(b.y * blocks.x + b.x) as usize] = true;
                        }
                        out.push(sprite);
                        continue;
                    }
                }
            }
            if rule.merge && inside(block) {
                let stats = stats(block);
                if stats.agrees(rule) {
                    out.push(stats.sprite((2 * block).as_vec2() + 1.0));
                    continue;
                }
            }
            for k in 0..4 {
                let p = texel(block, k);
                if !p.cmplt(size).all() {
                    continue;
                }
                let (color, coc, _) = value(p);
                if coc.abs() < min_coc {
                    continue;
                }
                out.push(Sprite {
                    center: p.as_vec2() + 0.5,
                    diameter: sprite_diameter(coc),
                    color,
                    weight: 1.0,
                    near: coc < 0.0,
                });
            }
        }
    }
    out
}

/// Whether sprite `s` is drawn at quarter resolution: it is at least `quarter_diameter`
/// half-resolution pixels wide.
pub fn is_quarter(s: &Sprite, quarter_diameter: f32) -> bool {
    s.diameter >= quarter_diameter
}

/// The layer sprite `s` is drawn into, in the scatter pass's order: 0 near and 1 far at
/// half resolution, 2 near and 3 far at quarter resolution.
pub fn layer_index(s: &Sprite, quarter_diameter: f32) -> usize {
    usize::from(!s.near) + 2 * usize::from(is_quarter(s, quarter_diameter))
}

/// The GPU's sprite list: [`sprites`]' list ordered by [`layer_index`], each layer in
/// block order, and where each layer starts.
pub fn by_layer(sprites: &[Sprite], quarter_diameter: f32) -> (Vec<Sprite>, [usize; 4]) {
    let mut list = Vec::with_capacity(sprites.len());
    let mut first = [0; 4];
    for (layer, start) in first.iter_mut().enumerate() {
        *start = list.len();
        list.extend(
            sprites
                .iter()
                .filter(|s| layer_index(s, quarter_diameter) == layer),
        );
    }
    (list, first)
}

/// The texels of a `size` target whose centres lie in the quad of `center` and `extent`
/// (left and top edges included), as the rasteriser picks them: `[x0, x1) × [y0, y1)`.
fn quad_texels(center: Vec2, extent: f32, size: UVec2) -> (u32, u32, u32, u32) {
    let lo = center - 0.5 * extent;
    let hi = center + 0.5 * extent;
    // Texels with centres in [lo, hi): x + ½ ≥ lo ⇔ x ≥ lo − ½.
    let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
    let x1 = ((hi.x - 0.5).ceil().max(0.0) as u32).min(size.x);
    let y1 = ((hi.y - 0.5).ceil().max(0.0) as u32).min(size.y);
    (x0, y0, x1, y1)
}

/// A sprite's quad in its own target: centre and extent in that target's pixels.
fn sprite_quad(s: &Sprite, quarter: bool) -> (Vec2, f32) {
    if quarter {
        // The half-resolution quad (one pixel wider for a block) halved, and half a
        // quarter texel more for the samples around each texel centre.
        (
            0.5 * s.center,
            0.5 * (quarter_diameter(s.diameter) + s.spread()) + 0.5,
        )
    } else {
        (s.center, s.diameter + s.spread())
    }
}

/// Rasterises every sprite into its layer, as the GPU's instanced quads do: a texel whose
/// centre lies in the quad (left and top edges included) adds `v` times the sprite's
/// mean colour and `v`, where `v` is [`sprite_weight`] at half resolution or
/// [`quarter_sprite_weight`] at quarter resolution (sprites at least `quarter_diameter`
/// wide), so every pixel spreads its energy once whatever its size.
pub fn scatter_sprites(
    sprites: &[Sprite],
    aperture: &Aperture,
    size: UVec2,
    quarter_diameter: f32,
) -> Layers {
    let n = (size.x * size.y) as usize;
    let quarter_size = (size + UVec2::ONE) / 2;
    let nq = (quarter_size.x * quarter_size.y) as usize;
    let mut layers = Layers {
        size,
        near: vec![Vec4::ZERO; n],
        far: vec![Vec4::ZERO; n],
        quarter_size,
        near_quarter: vec![Vec4::ZERO; nq],
        far_quarter: vec![Vec4::ZERO; nq],
    };
    for s in sprites {
        let quarter = is_quarter(s, quarter_diameter);
        let (center, extent) = sprite_quad(s, quarter);
        let target = if quarter { quarter_size } else { size };
        let (x0, y0, x1, y1) = quad_texels(center, extent, target);
        let color = s.color / s.weight;
        let layer = match (s.near, quarter) {
            (true, false) => &mut layers.near,
            (false, false) => &mut layers.far,
            (true, true) => &mut layers.near_quarter,
            (false, true) => &mut layers.far_quarter,
        };
        for y in y0..y1 {
            for x in x0..x1 {
                let p = Vec2::new(x as f32, y as f32) + 0.5;
                let v = if quarter {
                    quarter_sprite_weight(s, aperture, p)
                } else {
                    sprite_weight(s, aperture, p)
                };
                layer[(y * target.x + x) as usize] += (color * v).extend(v);
            }
        }
    }
    layers
}

/// The fragments the scatter pass shades (and blends) for `sprites` on a `size`
/// half-resolution target: the texels of every quad, at quarter resolution for sprites
/// at least `quarter_diameter` wide. The pass's work, counted.
pub fn scatter_fragments(sprites: &[Sprite], size: UVec2, quarter_diameter: f32) -> u64 {
    let quarter_size = (size + UVec2::ONE) / 2;
    sprites
        .iter()
        .map(|s| {
            let quarter = is_quarter(s, quarter_diameter);
            let (center, extent) = sprite_quad(s, quarter);
            let target = if quarter { quarter_size } else { size };
            let (x0, y0, x1, y1) = quad_texels(center, extent, target);
            u64::from(x1.saturating_sub(x0)) * u64::from(y1.saturating_sub(y0))
        })
        .sum()
}

/// What sprite `s` adds at half-resolution point `p` (a texel centre it covers): the
/// aperture around its pixel, or around each of its block's four, normalised so that
/// each pixel's sum over the texel centres is 1 (`Aperture::normalisation`).
pub fn sprite_weight(s: &Sprite, aperture: &Aperture, p: Vec2) -> f32 {
    // Near highlights show the aperture point-reflected.
    let at = |center: Vec2| aperture.sprite_sample(p - center, s.diameter, s.near);
    let side = s.side();
    let half = 0.5 * s.spread();
    let mut sum = 0.0;
    for y in 0..side {
        for x in 0..side {
            sum += at(s.center + (Vec2::new(x as f32, y as f32) - half));
        }
    }
    sum / aperture.normalisation(s.diameter)
}

/// The aperture diameter, half-resolution pixels, a sprite `diameter` wide is drawn with
/// at quarter resolution: shrunk by [`QUARTER_RES_BLUR`] so that the result's spread is
/// that of the same sprite at half resolution.
pub fn quarter_diameter(diameter: f32) -> f32 {
    (diameter * diameter - QUARTER_RES_BLUR).max(1.0).sqrt()
}

/// What sprite `s` adds at quarter-resolution point `p` (a quarter texel centre it
/// covers): what the sprite, drawn at half resolution with [`quarter_diameter`], adds at
/// the texel's four half-resolution texel centres ([`sprite_weight`]), summed: the
/// half-resolution layer the sprite would draw, summed 2×2, so it spreads exactly the
/// weight it does there. Sampling at half-resolution density keeps the aperture's edges
/// where one sample per quarter texel made them jagged (a 48 px highlight's shape
/// overlapped its aperture by 0.87 against 0.96 at half resolution) and blocks' sums
/// exact (3.4 % off with the four centres merged into one).
pub fn quarter_sprite_weight(s: &Sprite, aperture: &Aperture, p: Vec2) -> f32 {
    let shrunk = Sprite {
        diameter: quarter_diameter(s.diameter),
        ..*s
    };
    [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
        .into_iter()
        .map(|(x, y)| sprite_weight(&shrunk, aperture, 2.0 * p + Vec2::new(x, y)))
        .sum()
}

/// Bilinear sample, at full-resolution pixel `p`'s centre, of a layer of `size` texels
/// each `scale` full-resolution pixels wide (2: half, 4: quarter resolution).
fn layer_at(layer: &[Vec4], size: UVec2, p: UVec2, scale: f32) -> Vec4 {
    let q = (p.as_vec2() + 0.5) / scale - 0.5;
    let q0 = q.floor();
    let f = q - q0;
    let max = size.as_vec2() - 1.0;
    let texel = |x: f32, y: f32| {
        let x = x.clamp(0.0, max.x) as u32;
        let y = y.clamp(0.0, max.y) as u32;
        layer[(y * size.x + x) as usize]
    };
    let top = texel(q0.x, q0.y) * (1.0 - f.x) + texel(q0.x + 1.0, q0.y) * f.x;
    let bottom = texel(q0.x, q0.y + 1.0) * (1.0 - f.x) + texel(q0.x + 1.0, q0.y + 1.0) * f.x;
    top * (1.0 - f.y) + bottom * f.y
}

/// A layer's sums at full-resolution pixel `p`: the half-resolution layer's plus a
/// quarter of the quarter-resolution one's (a quarter texel covers four half texels).
fn layers_at(half: &[Vec4], quarter: &[Vec4], layers: &Layers, p: UVec2) -> Vec4 {
    layer_at(half, layers.size, p, 2.0) + layer_at(quarter, layers.quarter_size, p, 4.0) * 0.25
}

/// The full-resolution result: each pixel starts from the sharp image; behind the
/// focal plane it blends to the resolved far layer (`Σ colour / Σ weight`) as its own
/// circle of confusion grows from ½ pixel to `min_coc`; then the resolved near layer
/// is laid over it with opacity `min(Σ weight, 1)`. A pixel whose circle of confusion
/// is under ½ pixel and that no near sprite reaches keeps its input exactly.
pub fn composite(image: &BokehImage, lens: &Lens, rule: &SpriteRule, layers: &Layers) -> Vec<Vec3> {
    let full = image.size;
    let min_coc = rule.min_coc.max(0.5 + 1e-3);
    let mut out = Vec::with_capacity(image.color.len());
    for y in 0..full.y {
        for x in 0..full.x {
            let p = UVec2::new(x, y);
            let i = (y * full.x + x) as usize;
            let sharp = scene_color(image.color[i]);
            let coc = lens.coc(image.distance[i], full.y);
            let mut c = sharp;
            let far = layers_at(&layers.far, &layers.far_quarter, layers, p);
            if coc > 0.5 && far.w > 1e-6 {
                let t = ((coc - 0.5) / (min_coc - 0.5)).clamp(0.0, 1.0);
                c = sharp.lerp(far.truncate() / far.w, t);
            }
            let near = layers_at(&layers.near, &layers.near_quarter, layers, p);
            if near.w > 1e-6 {
                c = c.lerp(near.truncate() / near.w, near.w.min(1.0));
            }
            out.push(c);
        }
    }
    out
}

/// Every pass in order: the result and the sprites drawn.
pub fn depth_of_field(
    image: &BokehImage,
    lens: &Lens,
    aperture: &Aperture,
    rule: &SpriteRule,
) -> (Vec<Vec3>, Vec<Sprite>) {
    let half = downsample(image, lens);
    let sprites = sprites(&half, rule);
    let layers = scatter_sprites(&sprites, aperture, half.size, rule.quarter_diameter());
    (composite(image, lens, rule, &layers), sprites)
}
