//! The scatter bokeh passes: [`downsample`] to half resolution, [`sprites`] (one or
//! four per 2×2 block), [`scatter_sprites`] into the near and far layers, [`composite`]
//! at full resolution; [`depth_of_field`] runs them in order.
//!
//! Units: circles of confusion are signed diameters in **full-resolution** pixels
//! (negative in front of the focal plane); sprite positions and sizes are in
//! half-resolution pixels, `(0, 0)` the top-left corner of the half image.

use super::{Aperture, HALF_RES_BLUR, Lens, SpriteRule};
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
    /// How many half-resolution pixels it stands for: 1, or 4 for a 2×2 block, whose
    /// quad adds the aperture at each of the four pixel centres (the four sprites it
    /// replaces, drawn as one quad with a quarter of the blending).
    pub weight: f32,
    /// In front of the focal plane (the near layer), or behind it.
    pub near: bool,
}

/// The scatter pass's two half-resolution targets: `(Σ colour, Σ weight)` per texel.
#[derive(Clone, Debug)]
pub struct Layers {
    /// Half-resolution size.
    pub size: UVec2,
    /// In front of the focal plane.
    pub near: Vec<Vec4>,
    /// Behind it.
    pub far: Vec<Vec4>,
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
                color += image.color[i];
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

/// Whether the four texels of a block agree well enough for one sprite.
fn block_agrees(texels: &[(Vec3, f32, f32); 4], rule: &SpriteRule) -> bool {
    let range = |f: &dyn Fn(&(Vec3, f32, f32)) -> f32| {
        let values = texels.map(|t| f(&t));
        let lo = values.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        // Quarters first: four `f32::MAX` skies do not overflow.
        (lo, hi, values.iter().map(|v| v / 4.0).sum::<f32>())
    };
    let (coc_lo, coc_hi, _) = range(&|t| t.1);
    let same_side = coc_lo > 0.0 || coc_hi < 0.0;
    let (l_lo, l_hi, l_mean) = range(&|t| luminance(t.0));
    let (d_lo, d_hi, d_mean) = range(&|t| t.2);
    same_side
        && coc_hi - coc_lo <= rule.coc_tolerance
        && l_hi - l_lo <= rule.color_tolerance * l_mean.max(1e-4)
        && (d_hi - d_lo <= rule.depth_tolerance * d_mean || d_lo == d_hi)
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
/// circle of confusion reaches `rule.min_coc`. In block order, then
/// texel order within the block (the GPU's order differs; the sum does not).
pub fn sprites(half: &HalfImage, rule: &SpriteRule) -> Vec<Sprite> {
    let size = half.size;
    let blocks = (size + UVec2::ONE) / 2;
    let min_coc = rule.min_coc.max(1e-3);
    let mut out = Vec::new();
    for by in 0..blocks.y {
        for bx in 0..blocks.x {
            let texel = |k: u32| UVec2::new(2 * bx + (k & 1), 2 * by + (k >> 1));
            let inside = (0..4).all(|k| texel(k).cmplt(size).all());
            let value = |p: UVec2| {
                let i = (p.y * size.x + p.x) as usize;
                (half.color[i], half.coc[i], half.distance[i])
            };
            if rule.merge && inside {
                let texels = [0, 1, 2, 3].map(|k| value(texel(k)));
                if texels.iter().all(|t| t.1.abs() >= min_coc) && block_agrees(&texels, rule) {
                    let coc = texels.iter().map(|t| t.1).sum::<f32>() / 4.0;
                    out.push(Sprite {
                        center: (2 * UVec2::new(bx, by)).as_vec2() + 1.0,
                        diameter: sprite_diameter(coc),
                        color: texels.iter().map(|t| t.0).sum(),
                        weight: 4.0,
                        near: coc < 0.0,
                    });
                    continue;
                }
            }
            for k in 0..4 {
                let p = texel(k);
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

/// Rasterises every sprite into its layer of a `size` half-resolution target, as the
/// GPU's instanced quads do: a texel whose centre lies in the quad (left and top edges
/// included) adds `aperture(uv) / (mean · diameter²)` times the sprite's mean colour
/// and 1, for the sprite's pixel or each of a block's four (`uv` outside `[0, 1]²`
/// adds nothing), so every pixel spreads its energy once whatever its size.
pub fn scatter_sprites(sprites: &[Sprite], aperture: &Aperture, size: UVec2) -> Layers {
    let n = (size.x * size.y) as usize;
    let mut layers = Layers {
        size,
        near: vec![Vec4::ZERO; n],
        far: vec![Vec4::ZERO; n],
    };
    for s in sprites {
        let block = s.weight > 1.0;
        let extent = s.diameter + if block { 1.0 } else { 0.0 };
        let lo = s.center - 0.5 * extent;
        let hi = s.center + 0.5 * extent;
        // Texels with centres in [lo, hi): x + ½ ≥ lo ⇔ x ≥ lo − ½.
        let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
        let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
        let x1 = ((hi.x - 0.5).ceil().max(0.0) as u32).min(size.x);
        let y1 = ((hi.y - 0.5).ceil().max(0.0) as u32).min(size.y);
        let color = s.color / s.weight;
        let layer = if s.near {
            &mut layers.near
        } else {
            &mut layers.far
        };
        for y in y0..y1 {
            for x in x0..x1 {
                let v = sprite_weight(s, aperture, Vec2::new(x as f32, y as f32) + 0.5);
                layer[(y * size.x + x) as usize] += (color * v).extend(v);
            }
        }
    }
    layers
}

/// What sprite `s` adds at half-resolution point `p` (a texel centre it covers): the
/// aperture around its pixel, or around each of its block's four, normalised so that
/// each pixel's sum over the texel centres is 1 (`Aperture::normalisation`).
pub fn sprite_weight(s: &Sprite, aperture: &Aperture, p: Vec2) -> f32 {
    // Near highlights show the aperture point-reflected.
    let at = |center: Vec2| aperture.sprite_sample(p - center, s.diameter, s.near);
    let sum: f32 = if s.weight > 1.0 {
        [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
            .into_iter()
            .map(|(x, y)| at(s.center + Vec2::new(x, y)))
            .sum()
    } else {
        at(s.center)
    };
    sum / aperture.normalisation(s.diameter)
}

/// Bilinear sample of a half-resolution layer at full-resolution pixel `p`'s centre.
fn layer_at(layer: &[Vec4], size: UVec2, p: UVec2) -> Vec4 {
    let q = (p.as_vec2() + 0.5) * 0.5 - 0.5;
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
            let sharp = image.color[i];
            let coc = lens.coc(image.distance[i], full.y);
            let mut c = sharp;
            let far = layer_at(&layers.far, layers.size, p);
            if coc > 0.5 && far.w > 1e-6 {
                let t = ((coc - 0.5) / (min_coc - 0.5)).clamp(0.0, 1.0);
                c = sharp.lerp(far.truncate() / far.w, t);
            }
            let near = layer_at(&layers.near, layers.size, p);
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
    let layers = scatter_sprites(&sprites, aperture, half.size);
    (composite(image, lens, rule, &layers), sprites)
}
