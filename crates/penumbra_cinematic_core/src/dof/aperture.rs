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
}

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
        Ok(Aperture {
            size: width,
            weights,
            mean: mean as f32,
        })
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
}
