//! The bokeh shape: an aperture image, built in (circle, hexagon, polygon) or given,
//! checked and normalised once, shared by the plugin's texture and the CPU model.

use glam::Vec2;

/// Why an aperture image was rejected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ApertureError {
    /// No texels.
    Empty,
    /// Width and height differ.
    NotSquare {
        /// Texels across.
        width: u32,
        /// Texels down.
        height: u32,
    },
    /// The weights do not match the size.
    WrongLength {
        /// Width × height.
        expected: usize,
        /// Weights given.
        got: usize,
    },
    /// Every texel is zero (or not finite).
    Blank,
}

impl std::fmt::Display for ApertureError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ApertureError::Empty => write!(f, "the aperture image is empty"),
            ApertureError::NotSquare { width, height } => {
                write!(f, "the aperture image is {width}×{height}, not square")
            }
            ApertureError::WrongLength { expected, got } => {
                write!(f, "the aperture image has {got} texels, not {expected}")
            }
            ApertureError::Blank => write!(f, "the aperture image is blank"),
        }
    }
}

impl std::error::Error for ApertureError {}

/// The bokeh shape: a square image of transmission in `[0, 1]`, rows from the top,
/// sampled over the sprite's quad with bilinear filtering and clamped edges. It is the
/// aperture as seen from behind the camera: far highlights show it upright, near ones
/// point-reflected (their rays cross before the focal plane).
#[derive(Clone, Debug, PartialEq)]
pub struct Aperture {
    size: u32,
    weights: Vec<f32>,
    mean: f32,
    /// [`Aperture::norm_words`] less the mean.
    norm_table: Vec<f32>,
}

/// Sprite diameters (half-resolution pixels) below which a sprite is normalised by its
/// tabulated lattice sum rather than the aperture's analytic area.
pub const NORM_TABLE_MAX: f32 = 64.0;
/// Table intervals per doubling of the diameter: the table is uniform in `log d`, so the
/// outermost samples' positions `i / d` move by under a fifth of a texel of a 64-texel
/// image per step (64 steps: 1.2 % error at `d` ≈ 2; 128: under 0.6 %).
pub const NORM_TABLE_STEPS: u32 = 128;
/// Intervals of the table between diameters 1 and [`NORM_TABLE_MAX`].
pub const NORM_INTERVALS: usize = 6 * NORM_TABLE_STEPS as usize;

impl Aperture {
    /// An aperture from a `size × size` image (`weights` row-major, clamped to
    /// `[0, 1]`, non-finite values as 0).
    pub fn from_image(width: u32, height: u32, weights: &[f32]) -> Result<Self, ApertureError> {
        if width == 0 || height == 0 {
            return Err(ApertureError::Empty);
        }
        if width != height {
            return Err(ApertureError::NotSquare { width, height });
        }
        let expected = (width * height) as usize;
        if weights.len() != expected {
            return Err(ApertureError::WrongLength {
                expected,
                got: weights.len(),
            });
        }
        let weights: Vec<f32> = weights
            .iter()
            .map(|&w| {
                if w.is_finite() {
                    w.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect();
        let mean = weights.iter().map(|&w| f64::from(w)).sum::<f64>() / expected as f64;
        if mean <= 0.0 {
            return Err(ApertureError::Blank);
        }
        let mut aperture = Aperture {
            size: width,
            weights,
            mean: mean as f32,
            norm_table: Vec::new(),
        };
        aperture.norm_table = aperture.norm_tables();
        Ok(aperture)
    }

    /// A circle filling the image, its edge anti-aliased (4 × 4 samples per texel).
    pub fn circle(size: u32) -> Self {
        Self::from_inside(size, |p| p.length_squared() <= 1.0)
    }

    /// A regular hexagon with a vertex up, its circumscribed circle filling the image,
    /// its edges anti-aliased.
    pub fn hexagon(size: u32) -> Self {
        Self::polygon(size, 6, std::f32::consts::FRAC_PI_2)
    }

    /// A regular polygon of `sides` sides, a vertex at angle `rotation` (radians from
    /// +x, counter-clockwise with +y up), inscribed in the image's circle.
    pub fn polygon(size: u32, sides: u32, rotation: f32) -> Self {
        let sides = sides.max(3);
        let step = std::f32::consts::TAU / sides as f32;
        let apothem = (0.5 * step).cos();
        Self::from_inside(size, move |p| {
            (0..sides).all(|k| {
                // The edge between vertices k and k + 1 faces angle rotation + (k + ½) step.
                let a = rotation + (k as f32 + 0.5) * step;
                p.dot(Vec2::new(a.cos(), a.sin())) <= apothem
            })
        })
    }

    fn from_inside(size: u32, inside: impl Fn(Vec2) -> bool) -> Self {
        let size = size.max(1);
        let mut weights = Vec::with_capacity((size * size) as usize);
        for y in 0..size {
            for x in 0..size {
                let mut hits = 0;
                for j in 0..4 {
                    for i in 0..4 {
                        let t = Vec2::new(
                            (x as f32 + (i as f32 + 0.5) / 4.0) / size as f32,
                            (y as f32 + (j as f32 + 0.5) / 4.0) / size as f32,
                        );
                        // Image y down, shape y up; both in [−1, 1].
                        let p = Vec2::new(2.0 * t.x - 1.0, 1.0 - 2.0 * t.y);
                        hits += u32::from(inside(p));
                    }
                }
                weights.push(hits as f32 / 16.0);
            }
        }
        Self::from_image(size, size, &weights).expect("a shape covers its image's centre")
    }

    /// Texels along each side.
    pub fn size(&self) -> u32 {
        self.size
    }

    /// The transmission texels, row-major from the top.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// The mean transmission over the square: the shape's area as a fraction of it.
    pub fn mean(&self) -> f32 {
        self.mean
    }

    /// Bilinear sample at `uv` in `[0, 1]²` (texel centres at `(i + ½) / size`, edges
    /// clamped), as a linear-filtering, clamp-to-edge sampler reads it.
    pub fn sample(&self, uv: Vec2) -> f32 {
        let n = self.size as f32;
        let p = uv * n - 0.5;
        let p0 = p.floor();
        let f = p - p0;
        let texel = |x: f32, y: f32| {
            let x = x.clamp(0.0, n - 1.0) as u32;
            let y = y.clamp(0.0, n - 1.0) as u32;
            self.weights[(y * self.size + x) as usize]
        };
        let top = texel(p0.x, p0.y) * (1.0 - f.x) + texel(p0.x + 1.0, p0.y) * f.x;
        let bottom = texel(p0.x, p0.y + 1.0) * (1.0 - f.x) + texel(p0.x + 1.0, p0.y + 1.0) * f.x;
        top * (1.0 - f.y) + bottom * f.y
    }

    /// Whether texel offset `o` (half-resolution pixels) from a sprite's centre lies in
    /// its aperture's image, `diameter` wide: `|o| < d/2` on each axis (strictly: inside
    /// the sprite's quad whichever edges the rasteriser keeps).
    pub fn covers(offset: Vec2, diameter: f32) -> bool {
        offset.abs().cmplt(Vec2::splat(0.5 * diameter)).all()
    }

    /// The aperture as a sprite of `diameter` half-resolution pixels sees it at texel
    /// offset `offset` from its centre: 0 outside ([`Aperture::covers`]), point-reflected
    /// for a near sprite.
    pub fn sprite_sample(&self, offset: Vec2, diameter: f32, near: bool) -> f32 {
        if !Self::covers(offset, diameter) {
            return 0.0;
        }
        let uv = offset / diameter + 0.5;
        self.sample(if near { Vec2::ONE - uv } else { uv })
    }

    /// What a sprite of `diameter` half-resolution pixels, centred on a texel, sums to
    /// over the texel offsets it covers. Small sprites see only a few samples of the
    /// image, whose sum is far from its area `mean · d²`: 1 sample for `d` = 1.5 against
    /// an area of 1.46 (hexagon). The sum jumps just past even diameters `2m`, where the
    /// offsets `±m` start being covered (at the image's edge, not transparent for a
    /// circle touching it). The covered offsets are symmetric, so a near sprite's
    /// point-reflected aperture sums to the same.
    pub fn lattice_sum(&self, diameter: f32) -> f32 {
        let d = diameter.max(1e-3);
        let reach = (0.5 * d).ceil() as i32;
        let mut sum = 0.0f64;
        for j in -reach..=reach {
            for i in -reach..=reach {
                let o = Vec2::new(i as f32, j as f32);
                sum += f64::from(self.sprite_sample(o, d, false));
            }
        }
        sum as f32
    }

    /// The normalisation of a sprite of `diameter` half-resolution pixels, so that it
    /// spreads unit weight over the texels it covers: its lattice sum under
    /// [`NORM_TABLE_MAX`], the analytic area `mean · d²` above. The table has an interval
    /// per step of `log₂ d` (`1 / NORM_TABLE_STEPS`): the sum at its start, its
    /// continuous part at its end (linear between in `log₂ d`), and the jump past the even
    /// diameter in it. Never below 1/16 of the area. The GPU reads the same table ([`Aperture::norm_words`]).
    pub fn normalisation(&self, diameter: f32) -> f32 {
        let d = diameter.max(1.0);
        let area = self.mean * d * d;
        if d >= NORM_TABLE_MAX {
            return area;
        }
        let t = d.log2() * NORM_TABLE_STEPS as f32;
        let k = (t as usize).min(NORM_INTERVALS - 1);
        let f = t - k as f32;
        let e = &self.norm_table[4 * k..][..4];
        let mut sum = e[0] * (1.0 - f) + e[1] * f;
        if d > e[3] {
            sum += e[2];
        }
        sum.max(area / 16.0)
    }

    /// The scatter shader's `aperture_norm` buffer: the mean, then per interval of
    /// [`Aperture::normalisation`]'s table its sum at the start, continuous part at the
    /// end, jump and the diameter of the jump (infinity when none).
    pub fn norm_words(&self) -> Vec<f32> {
        std::iter::once(self.mean)
            .chain(self.norm_table.iter().copied())
            .collect()
    }

    fn norm_tables(&self) -> Vec<f32> {
        let d = |k: usize| (k as f32 / NORM_TABLE_STEPS as f32).exp2();
        let mut out = Vec::with_capacity(4 * NORM_INTERVALS);
        for k in 0..NORM_INTERVALS {
            let (d0, d1) = (d(k), d(k + 1));
            // The even diameter at or after the start; its offsets enter just past it.
            let even = 2.0 * (0.5 * d0).ceil();
            let (jump, at) = if even < d1 {
                let past = (even + 1e-3).min(0.5 * (even + d1));
                (self.lattice_sum(past) - self.lattice_sum(even), even)
            } else {
                (0.0, f32::INFINITY)
            };
            out.extend([self.lattice_sum(d0), self.lattice_sum(d1) - jump, jump, at]);
        }
        out
    }
}
