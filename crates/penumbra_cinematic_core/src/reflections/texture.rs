//! Billboard images as the pass samples them: premultiplied linear RGBA in a mip chain
//! (2 × 2 box filter), rounded to `f16` as the texture array's `Rgba16Float` stores
//! them, and the trilinear filter (clamp to edge, explicit level) the shader's sampler
//! applies — so the CPU model reads the very texels the GPU does.

use glam::{Vec2, Vec4};

/// One billboard image's mip chain: level 0 is the image (premultiplied alpha), each
/// next level half the size (at least 1 texel), every texel rounded to `f16`.
#[derive(Clone, Debug, PartialEq)]
pub struct MipChain {
    /// Level 0's width, texels.
    pub width: u32,
    /// Level 0's height, texels.
    pub height: u32,
    /// Texels of each level, row-major from the top left.
    pub levels: Vec<Vec<Vec4>>,
}

/// Levels of a full chain for a `width × height` image: `⌊log2 max⌋ + 1`.
pub fn mip_count(width: u32, height: u32) -> u32 {
    32 - width.max(height).max(1).leading_zeros()
}

/// `x` rounded to the nearest `f16` (as stored in an `Rgba16Float` texture), back in
/// `f32`.
pub fn round_to_f16(x: f32) -> f32 {
    half::f16::from_f32(x).to_f32()
}

fn round4(v: Vec4) -> Vec4 {
    Vec4::new(
        round_to_f16(v.x),
        round_to_f16(v.y),
        round_to_f16(v.z),
        round_to_f16(v.w),
    )
}

impl MipChain {
    /// The chain of an image of straight-alpha linear texels (`width × height`, row-major
    /// from the top left): premultiplied, then each level the mean of its parent's 2 × 2
    /// block (odd sizes drop the last row or column), computed in `f32` from the
    /// unrounded parent and rounded to `f16`. Non-finite values become 0 and alpha is
    /// clamped to `[0, 1]`.
    ///
    /// # Panics
    /// When `texels.len() != width × height` or a side is 0 (the plugin checks first).
    pub fn from_straight_alpha(width: u32, height: u32, texels: &[Vec4]) -> Self {
        assert!(width > 0 && height > 0 && texels.len() == (width * height) as usize);
        let mut exact: Vec<Vec4> = texels
            .iter()
            .map(|t| {
                let t = Vec4::select(t.is_finite_mask(), *t, Vec4::ZERO);
                let a = t.w.clamp(0.0, 1.0);
                (t.truncate().max(glam::Vec3::ZERO) * a).extend(a)
            })
            .collect();
        let (mut w, mut h) = (width, height);
        let mut levels = vec![exact.iter().copied().map(round4).collect()];
        for _ in 1..mip_count(width, height) {
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            let mut next = Vec::with_capacity((nw * nh) as usize);
            for y in 0..nh {
                for x in 0..nw {
                    let at = |dx: u32, dy: u32| {
                        exact[((2 * y + dy).min(h - 1) * w + (2 * x + dx).min(w - 1)) as usize]
                    };
                    next.push((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)) * 0.25);
                }
            }
            levels.push(next.iter().copied().map(round4).collect());
            (exact, w, h) = (next, nw, nh);
        }
        MipChain {
            width,
            height,
            levels,
        }
    }

    /// `(width, height)` of `level`.
    pub fn level_size(&self, level: usize) -> (u32, u32) {
        ((self.width >> level).max(1), (self.height >> level).max(1))
    }

    /// Bilinear sample of one level at `uv` (`(0, 0)` the top left corner), clamped to
    /// the edge.
    pub fn bilinear(&self, level: usize, uv: Vec2) -> Vec4 {
        let (w, h) = self.level_size(level);
        let texels = &self.levels[level];
        let p = uv * Vec2::new(w as f32, h as f32) - 0.5;
        let p0 = p.floor();
        let f = p - p0;
        let at = |x: f32, y: f32| {
            let x = (x.max(0.0) as u32).min(w - 1);
            let y = (y.max(0.0) as u32).min(h - 1);
            texels[(y * w + x) as usize]
        };
        let top = at(p0.x, p0.y).lerp(at(p0.x + 1.0, p0.y), f.x);
        let bottom = at(p0.x, p0.y + 1.0).lerp(at(p0.x + 1.0, p0.y + 1.0), f.x);
        top.lerp(bottom, f.y)
    }

    /// Trilinear sample at `uv` and level of detail `lod` (clamped to the chain), as
    /// WGSL's `textureSampleLevel` with linear min, mag and mip filters.
    pub fn sample(&self, uv: Vec2, lod: f32) -> Vec4 {
        let last = self.levels.len() - 1;
        let lod = lod.clamp(0.0, last as f32);
        let l0 = lod.floor() as usize;
        let f = lod - l0 as f32;
        if l0 >= last || f == 0.0 {
            return self.bilinear(l0.min(last), uv);
        }
        self.bilinear(l0, uv).lerp(self.bilinear(l0 + 1, uv), f)
    }

    /// Every level's texels as `f16` bits (RGBA, level after level): the texture
    /// array layer's upload.
    pub fn f16_bits(&self) -> Vec<u16> {
        self.levels
            .iter()
            .flatten()
            .flat_map(|t| t.to_array())
            .map(|x| half::f16::from_f32(x).to_bits())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_sizes_and_means() {
        assert_eq!(mip_count(1, 1), 1);
        assert_eq!(mip_count(4, 4), 3);
        assert_eq!(mip_count(5, 2), 3);
        assert_eq!(mip_count(256, 64), 9);
        // A 4×2 image: left half opaque red, right half half-transparent white.
        let texels: Vec<Vec4> = (0..8)
            .map(|i| {
                if i % 4 < 2 {
                    Vec4::new(1.0, 0.0, 0.0, 1.0)
                } else {
                    Vec4::new(1.0, 1.0, 1.0, 0.5)
                }
            })
            .collect();
        let chain = MipChain::from_straight_alpha(4, 2, &texels);
        assert_eq!(chain.levels.len(), 3);
        assert_eq!(chain.level_size(1), (2, 1));
        assert_eq!(chain.level_size(2), (1, 1));
        // Premultiplied: the white half holds (0.5, 0.5, 0.5, 0.5).
        assert_eq!(chain.levels[0][3], Vec4::splat(0.5));
        assert_eq!(
            chain.levels[1],
            vec![Vec4::new(1.0, 0.0, 0.0, 1.0), Vec4::splat(0.5)]
        );
        assert_eq!(chain.levels[2], vec![Vec4::new(0.75, 0.25, 0.25, 0.75)]);
        assert_eq!(chain.f16_bits().len(), (8 + 2 + 1) * 4);
    }

    #[test]
    fn trilinear_sampling() {
        let texels: Vec<Vec4> = (0..4).map(|i| Vec4::splat(i as f32 / 4.0)).collect();
        let chain = MipChain::from_straight_alpha(2, 2, &texels);
        // Premultiplied (x · a), alpha as given.
        let t = |i: usize| chain.levels[0][i];
        // Texel centres return the texels; the corner clamps to the edge.
        assert_eq!(chain.sample(Vec2::new(0.25, 0.25), 0.0), t(0));
        assert_eq!(chain.sample(Vec2::new(0.75, 0.75), 0.0), t(3));
        assert_eq!(chain.sample(Vec2::ZERO, 0.0), t(0));
        // Between the four: their mean; level 1 is the mean everywhere.
        let mean = (t(0) + t(1) + t(2) + t(3)) * 0.25;
        assert!(
            (chain.sample(Vec2::splat(0.5), 0.0) - mean)
                .abs()
                .max_element()
                < 1e-3
        );
        assert!(
            (chain.sample(Vec2::new(0.1, 0.9), 1.0) - mean)
                .abs()
                .max_element()
                < 1e-3
        );
        // Half a level: halfway between the texel and the mean; past the end: clamped.
        let half_way = (t(0) + mean) * 0.5;
        assert!(
            (chain.sample(Vec2::splat(0.25), 0.5) - half_way)
                .abs()
                .max_element()
                < 1e-3
        );
        assert_eq!(
            chain.sample(Vec2::splat(0.25), 7.0),
            chain.sample(Vec2::ZERO, 1.0)
        );
    }

    #[test]
    fn bad_texels_are_cleaned() {
        let texels = [
            Vec4::new(f32::NAN, 1.0, 1.0, 1.0),
            Vec4::new(1.0, 1.0, 1.0, 2.0),
            Vec4::new(-1.0, 1.0, 1.0, -1.0),
            Vec4::new(f32::INFINITY, 0.0, 0.0, 1.0),
        ];
        let chain = MipChain::from_straight_alpha(2, 2, &texels);
        assert_eq!(chain.levels[0][0], Vec4::new(0.0, 1.0, 1.0, 1.0));
        assert_eq!(chain.levels[0][1], Vec4::ONE);
        assert_eq!(chain.levels[0][2], Vec4::ZERO);
        assert_eq!(chain.levels[0][3], Vec4::new(0.0, 0.0, 0.0, 1.0));
        assert!(chain.levels.iter().flatten().all(|t| t.is_finite()));
    }
}
