//! Patch evaluation: PN and PN-AEN control points, the canonical edge curve, the
//! displacement map's mip chain and its trilinear sample. The WGSL twin is
//! `shaders/tessellation/patch.wgsl`; expressions are written in the same order.

use super::preprocess::TessellationInput;
use super::{Settings, SurfaceMode};
use glam::{Vec2, Vec3};

/// The PN control point of edge `a → b` next to `a`, with `a`'s normal `n`
/// (Vlachos et al.: `(2a + b − ((b − a)·n) n) / 3`).
pub fn pn_edge_point(a: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    (a * 2.0 + b - n * (b - a).dot(n)) / 3.0
}

/// The PN mid-edge normal of edge `a → b` with normals `na`, `nb`.
pub fn pn_edge_normal(a: Vec3, b: Vec3, na: Vec3, nb: Vec3) -> Vec3 {
    let d = b - a;
    let v = 2.0 * d.dot(na + nb) / d.dot(d).max(1e-30);
    (na + nb - d * v).normalize_or_zero()
}

/// A cubic Bézier curve's point at `t` (Bernstein form).
pub fn bezier(p0: Vec3, c0: Vec3, c1: Vec3, p1: Vec3, t: f32) -> Vec3 {
    let s = 1.0 - t;
    p0 * (s * s * s) + c0 * (3.0 * s * s * t) + c1 * (3.0 * s * t * t) + p1 * (t * t * t)
}

/// An edge as both its triangles evaluate it: endpoints in canonical order, the cubic's
/// inner control points, the dominant edge's UVs and the displacement directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeCurve {
    /// First endpoint (the lower dominant vertex when crack fixes are on).
    pub p0: Vec3,
    /// Second endpoint.
    pub p1: Vec3,
    /// Control point next to `p0`.
    pub c0: Vec3,
    /// Control point next to `p1`.
    pub c1: Vec3,
    /// Texture coordinates at `p0` and `p1` (the dominant edge's).
    pub uv0: Vec2,
    /// See [`Self::uv0`].
    pub uv1: Vec2,
    /// Displacement directions at `p0` and `p1`.
    pub n0: Vec3,
    /// See [`Self::n0`].
    pub n1: Vec3,
    /// Whether the canonical order is the triangle's reverse.
    pub reversed: bool,
}

/// Edge `e` (corner `e` → `e + 1`) of `patch`.
pub fn edge_curve(
    input: &TessellationInput,
    patch: &[u32; 12],
    e: usize,
    settings: &Settings,
) -> EdgeCurve {
    let v = |i: u32| &input.vertices[i as usize];
    let (a, b) = (patch[e], patch[(e + 1) % 3]);
    if !settings.crack_fixes {
        let (va, vb) = (v(a), v(b));
        return EdgeCurve {
            p0: va.position,
            p1: vb.position,
            c0: pn_edge_point(va.position, vb.position, va.normal),
            c1: pn_edge_point(vb.position, va.position, vb.normal),
            uv0: va.uv,
            uv1: vb.uv,
            n0: va.normal,
            n1: vb.normal,
            reversed: false,
        };
    }
    let (oa, ob) = (patch[3 + 2 * e], patch[4 + 2 * e]);
    let (da, db) = (patch[9 + e], patch[9 + (e + 1) % 3]);
    let reversed = db < da;
    // The two pairs, each as (vertex at the first endpoint, at the second).
    let orient = |x: u32, y: u32| if reversed { (y, x) } else { (x, y) };
    let own = orient(a, b);
    let opposite = orient(oa, ob);
    let key = |p: (u32, u32)| (p.0.min(p.1), p.0.max(p.1));
    let (dom, other) = if key(opposite) < key(own) {
        (opposite, own)
    } else {
        (own, opposite)
    };
    let (d0, d1) = orient(da, db);
    let (p0, p1) = (v(d0).position, v(d1).position);
    let c0 =
        (pn_edge_point(p0, p1, v(dom.0).normal) + pn_edge_point(p0, p1, v(other.0).normal)) * 0.5;
    let c1 =
        (pn_edge_point(p1, p0, v(dom.1).normal) + pn_edge_point(p1, p0, v(other.1).normal)) * 0.5;
    EdgeCurve {
        p0,
        p1,
        c0,
        c1,
        uv0: v(dom.0).uv,
        uv1: v(dom.1).uv,
        n0: v(d0).smooth_normal,
        n1: v(d1).smooth_normal,
        reversed,
    }
}

impl EdgeCurve {
    /// The undisplaced point at canonical parameter `t`.
    pub fn point(&self, t: f32, mode: SurfaceMode) -> Vec3 {
        match mode {
            SurfaceMode::Flat => self.p0 * (1.0 - t) + self.p1 * t,
            SurfaceMode::PnAen => bezier(self.p0, self.c0, self.c1, self.p1, t),
        }
    }

    /// Texture coordinates and displacement direction at `t`.
    pub fn uv_and_direction(&self, t: f32) -> (Vec2, Vec3) {
        let s = 1.0 - t;
        (
            self.uv0 * s + self.uv1 * t,
            (self.n0 * s + self.n1 * t).normalize_or_zero(),
        )
    }

    /// The inner control points in the triangle's order (next to corner `e`, to `e + 1`).
    pub fn own_control_points(&self) -> (Vec3, Vec3) {
        if self.reversed {
            (self.c1, self.c0)
        } else {
            (self.c0, self.c1)
        }
    }
}

/// A PN triangle's ten control points from its corners and edge control points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PnPatch {
    /// Corners 0, 1, 2.
    pub corners: [Vec3; 3],
    /// Per edge `e`, the control points next to corner `e` and `e + 1`.
    pub edges: [(Vec3, Vec3); 3],
    /// The centre control point `b111 = E + (E − V)/2`.
    pub centre: Vec3,
}

impl PnPatch {
    /// The patch of `corners` with the given edge control points.
    pub fn new(corners: [Vec3; 3], edges: [(Vec3, Vec3); 3]) -> Self {
        let e = (edges[0].0 + edges[0].1 + edges[1].0 + edges[1].1 + edges[2].0 + edges[2].1) / 6.0;
        let v = (corners[0] + corners[1] + corners[2]) / 3.0;
        Self {
            corners,
            edges,
            centre: e + (e - v) * 0.5,
        }
    }

    /// The plain PN patch of three positions and normals.
    pub fn pn(p: [Vec3; 3], n: [Vec3; 3]) -> Self {
        let edges = [0, 1, 2].map(|e| {
            let f = (e + 1) % 3;
            (
                pn_edge_point(p[e], p[f], n[e]),
                pn_edge_point(p[f], p[e], n[f]),
            )
        });
        Self::new(p, edges)
    }

    /// The point at barycentric `b` (weights of corners 0, 1, 2).
    pub fn point(&self, b: Vec3) -> Vec3 {
        let (w, u, v) = (b.x, b.y, b.z);
        let [p0, p1, p2] = self.corners;
        let [(b210, b120), (b021, b012), (b102, b201)] = self.edges;
        p0 * (w * w * w)
            + p1 * (u * u * u)
            + p2 * (v * v * v)
            + b210 * (3.0 * w * w * u)
            + b120 * (3.0 * w * u * u)
            + b201 * (3.0 * w * w * v)
            + b021 * (3.0 * u * u * v)
            + b102 * (3.0 * w * v * v)
            + b012 * (3.0 * u * v * v)
            + self.centre * (6.0 * w * u * v)
    }
}

/// PN's quadratic normal at `b` from the corners' positions and normals.
pub fn pn_normal(p: [Vec3; 3], n: [Vec3; 3], b: Vec3) -> Vec3 {
    let (w, u, v) = (b.x, b.y, b.z);
    let n110 = pn_edge_normal(p[0], p[1], n[0], n[1]);
    let n011 = pn_edge_normal(p[1], p[2], n[1], n[2]);
    let n101 = pn_edge_normal(p[2], p[0], n[2], n[0]);
    (n[0] * (w * w)
        + n[1] * (u * u)
        + n[2] * (v * v)
        + n110 * (w * u)
        + n011 * (u * v)
        + n101 * (w * v))
        .normalize_or_zero()
}

/// The surface gradients of `u` and `v` over a flat triangle (local units⁻¹), for
/// bending the normal by the height's slope; zero for a degenerate triangle or UVs.
pub fn uv_gradients(p: [Vec3; 3], uv: [Vec2; 3]) -> (Vec3, Vec3) {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = a * c - b * b;
    if det <= 1e-20 * a * c || det == 0.0 {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    let grad = |x1: f32, x2: f32| {
        let alpha = (c * x1 - b * x2) / det;
        let beta = (a * x2 - b * x1) / det;
        e1 * alpha + e2 * beta
    };
    (grad(d1.x, d2.x), grad(d1.y, d2.y))
}

/// A height map's mip chain: level 0 the image's red channel, each next level the 2×2
/// box average (a lone last row or column is repeated), down to 1×1. Addressing
/// repeats. The GPU reads the same texels from a storage buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct DisplacementMap {
    /// Per level: width, height and first texel in [`Self::texels`].
    pub levels: Vec<[u32; 3]>,
    /// All levels' texels, row-major.
    pub texels: Vec<f32>,
}

/// The most mip levels a displacement map keeps (a 32,768² image has 16).
pub const MAX_DISPLACEMENT_LEVELS: usize = 16;

impl DisplacementMap {
    /// The chain of a `width × height` image of heights (row-major); `None` when empty,
    /// mis-sized or holding a non-finite height.
    pub fn new(width: u32, height: u32, texels: Vec<f32>) -> Option<Self> {
        if width == 0 || height == 0 || texels.len() != (width as usize) * (height as usize) {
            return None;
        }
        if texels.iter().any(|t| !t.is_finite()) {
            return None;
        }
        let mut map = Self {
            levels: vec![[width, height, 0]],
            texels,
        };
        while map.levels.len() < MAX_DISPLACEMENT_LEVELS {
            let [w, h, _] = *map.levels.last().expect("level 0");
            if w == 1 && h == 1 {
                break;
            }
            let level = map.levels.len() - 1;
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            let offset = map.texels.len() as u32;
            for y in 0..nh {
                for x in 0..nw {
                    let (x0, y0) = (2 * x, 2 * y);
                    let (x1, y1) = ((2 * x + 1).min(w - 1), (2 * y + 1).min(h - 1));
                    let t = |x, y| map.texel(level, x, y);
                    let avg = (t(x0, y0) + t(x1, y0) + t(x0, y1) + t(x1, y1)) * 0.25;
                    map.texels.push(avg);
                }
            }
            map.levels.push([nw, nh, offset]);
        }
        Some(map)
    }

    /// Level 0's size.
    pub fn size(&self) -> Vec2 {
        Vec2::new(self.levels[0][0] as f32, self.levels[0][1] as f32)
    }

    fn texel(&self, level: usize, x: u32, y: u32) -> f32 {
        let [w, _, offset] = self.levels[level];
        self.texels[(offset + y * w + x) as usize]
    }

    /// Bilinear sample of `level` at `uv`, repeating.
    pub fn bilinear(&self, level: usize, uv: Vec2) -> f32 {
        let [w, h, _] = self.levels[level];
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        let (fx, fy) = (x - x.floor(), y - y.floor());
        let wrap = |i: f32, n: u32| (i as i64).rem_euclid(n as i64) as u32;
        let (x0, y0) = (wrap(x.floor(), w), wrap(y.floor(), h));
        let (x1, y1) = ((x0 + 1) % w, (y0 + 1) % h);
        let top = self.texel(level, x0, y0) * (1.0 - fx) + self.texel(level, x1, y0) * fx;
        let bottom = self.texel(level, x0, y1) * (1.0 - fx) + self.texel(level, x1, y1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Trilinear sample at `uv` and mip `lod` (clamped to the chain).
    pub fn sample(&self, uv: Vec2, lod: f32) -> f32 {
        let last = (self.levels.len() - 1) as f32;
        let lod = lod.clamp(0.0, last);
        let l0 = lod.floor();
        let l1 = (l0 + 1.0).min(last);
        let t = lod - l0;
        let a = self.bilinear(l0 as usize, uv);
        let b = self.bilinear(l1 as usize, uv);
        a * (1.0 - t) + b * t
    }

    /// The height's slope `(∂h/∂u, ∂h/∂v)` at `uv`, by central differences one texel of
    /// mip `lod` apart.
    pub fn slope(&self, uv: Vec2, lod: f32) -> Vec2 {
        let step = Vec2::splat(lod.clamp(0.0, (self.levels.len() - 1) as f32).exp2()) / self.size();
        let du = self.sample(uv + Vec2::new(step.x, 0.0), lod)
            - self.sample(uv - Vec2::new(step.x, 0.0), lod);
        let dv = self.sample(uv + Vec2::new(0.0, step.y), lod)
            - self.sample(uv - Vec2::new(0.0, step.y), lod);
        Vec2::new(du / (2.0 * step.x), dv / (2.0 * step.y))
    }

    /// The mip where a span of `uv_span` texture coordinates cut at factor `factor` (about
    /// `factor` segments) covers about one texel per segment, at least 0.
    pub fn lod_for(&self, uv_span: Vec2, factor: f32) -> f32 {
        ((uv_span * self.size()).length() / factor).max(1.0).log2()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pn_interpolates_corners_and_their_normals() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let n = [
            Vec3::new(-0.3, -0.3, 1.0).normalize(),
            Vec3::new(0.5, 0.0, 1.0).normalize(),
            Vec3::new(0.0, 0.4, 1.0).normalize(),
        ];
        let patch = PnPatch::pn(p, n);
        let corners = [Vec3::X, Vec3::Y, Vec3::Z];
        for c in 0..3 {
            assert!((patch.point(corners[c]) - p[c]).length() < 1e-6);
            // The tangent plane at the corner is normal to n: finite differences along
            // two directions from the corner.
            let h = 1e-3;
            let others = [(c + 1) % 3, (c + 2) % 3];
            for o in others {
                let b = corners[c] * (1.0 - h) + corners[o] * h;
                let t = (patch.point(b) - p[c]) / h;
                assert!(
                    t.normalize().dot(n[c]).abs() < 2e-3,
                    "corner {c} toward {o}"
                );
            }
        }
        // Face normals everywhere: the flat triangle.
        let flat = PnPatch::pn(p, [Vec3::Z; 3]);
        let b = Vec3::new(0.2, 0.3, 0.5);
        assert!((flat.point(b) - (p[1] * 0.3 + p[2] * 0.5)).length() < 1e-6);
    }

    #[test]
    fn the_bernstein_form_is_de_casteljau() {
        let pts = [
            Vec3::ZERO,
            Vec3::new(0.3, 1.0, 0.0),
            Vec3::new(0.9, -0.5, 0.2),
            Vec3::X,
        ];
        for k in 0..=10 {
            let t = k as f32 / 10.0;
            let mut q = pts.to_vec();
            while q.len() > 1 {
                q = q.windows(2).map(|w| w[0].lerp(w[1], t)).collect();
            }
            assert!((bezier(pts[0], pts[1], pts[2], pts[3], t) - q[0]).length() < 1e-6);
        }
    }

    #[test]
    fn mips_average_and_samples_repeat() {
        let map = DisplacementMap::new(4, 2, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]).unwrap();
        assert_eq!(map.levels, vec![[4, 2, 0], [2, 1, 8], [1, 1, 10]]);
        assert_eq!(map.texels[8..], [2.5, 4.5, 3.5]);
        // Texel centres read exactly; the edge wraps.
        assert_eq!(map.bilinear(0, Vec2::new(0.125, 0.25)), 0.0);
        assert_eq!(map.bilinear(0, Vec2::new(0.0, 0.25)), 1.5);
        assert_eq!(map.sample(Vec2::new(0.125, 0.25), 9.0), 3.5);
        assert!(DisplacementMap::new(2, 2, vec![0.0; 3]).is_none());
        assert!(DisplacementMap::new(1, 1, vec![f32::NAN]).is_none());
    }
}
