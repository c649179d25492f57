//! The CPU reference tessellator: the GPU passes' model (`shaders/tessellation/`), vertex
//! for vertex, and the measurements the tests and benches take of its output.

use super::factors::{TessellationView, biased, choose_bias, demand, edge_factor, level_of};
use super::patch::{DisplacementMap, EdgeCurve, PnPatch, edge_curve, pn_normal, uv_gradients};
use super::preprocess::{TessVertex, TessellationInput};
use super::{Partitioning, Settings, SurfaceMode, grid_index, grid_triangles};
use glam::{Mat4, Vec2, Vec3, Vec4};

/// Where the mesh is and who looks at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The camera.
    pub view: TessellationView,
    /// The mesh's transform.
    pub world_from_local: Mat4,
}

impl Frame {
    /// Local units per world unit (`|det|^(−1/3)`, a uniform scale's inverse).
    pub fn local_per_world(&self) -> f32 {
        let det = self.world_from_local.determinant().abs();
        if det > 0.0 && det.is_finite() {
            det.powf(-1.0 / 3.0)
        } else {
            1.0
        }
    }
}

/// A patch's factors and levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchLod {
    /// Each edge's factor after the bias.
    pub edge_factors: [f32; 3],
    /// Each edge's level and morph.
    pub edge_levels: [(u32, f32); 3],
    /// The patch's factor (the largest edge's).
    pub factor: f32,
    /// The patch's level and morph.
    pub level: (u32, f32),
}

/// Each edge's unbiased factor (world positions in the edge's canonical order).
pub fn patch_edge_factors(
    input: &TessellationInput,
    patch: &[u32; 12],
    frame: &Frame,
    settings: &Settings,
) -> [f32; 3] {
    [0, 1, 2].map(|e| {
        let curve = edge_curve(input, patch, e, settings);
        let a = frame.world_from_local.transform_point3(curve.p0);
        let b = frame.world_from_local.transform_point3(curve.p1);
        edge_factor(
            &frame.view,
            a,
            b,
            settings.pixels_per_triangle,
            settings.max_level,
        )
    })
}

/// Levels and morphs of a patch's factors after `bias`.
pub fn patch_lod(factors: [f32; 3], bias: u32, partitioning: Partitioning) -> PatchLod {
    let edge_factors = factors.map(|f| biased(f, bias));
    let factor = edge_factors[0].max(edge_factors[1]).max(edge_factors[2]);
    PatchLod {
        edge_factors,
        edge_levels: edge_factors.map(|f| level_of(f, partitioning)),
        factor,
        level: level_of(factor, partitioning),
    }
}

/// A tessellated mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TessellatedMesh {
    /// Positions (local units).
    pub positions: Vec<Vec3>,
    /// Shading normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates (the triangle's own).
    pub uvs: Vec<Vec2>,
    /// Tangents (zero when the input has none).
    pub tangents: Vec<Vec4>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Per patch: first vertex, first index and its [`PatchLod`].
    pub patches: Vec<(u32, u32, PatchLod)>,
    /// The bias that fitted the budget.
    pub bias: u32,
}

/// One output vertex before it is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutVertex {
    /// Position.
    pub position: Vec3,
    /// Shading normal.
    pub normal: Vec3,
    /// Barycentric coordinates (own corners) the UV and tangent interpolate at.
    pub bary: Vec3,
}

/// Everything a patch's vertices need.
pub struct PatchEval<'a> {
    input: &'a TessellationInput,
    settings: &'a Settings,
    map: Option<&'a DisplacementMap>,
    own: [TessVertex; 3],
    dominant: [TessVertex; 3],
    curves: [EdgeCurve; 3],
    surface: PnPatch,
    gradients: (Vec3, Vec3),
    lod: PatchLod,
    corner_lods: [f32; 3],
    patch_lod: f32,
}

impl<'a> PatchEval<'a> {
    /// Prepares patch `p` at `lod` (after `bias`) for `frame`.
    pub fn new(
        input: &'a TessellationInput,
        p: usize,
        frame: &Frame,
        settings: &'a Settings,
        map: Option<&'a DisplacementMap>,
        lod: PatchLod,
        bias: u32,
    ) -> Self {
        let patch = &input.patches[p];
        let own = [0, 1, 2].map(|c| input.vertices[patch[c] as usize]);
        let dominant = if settings.crack_fixes {
            [0, 1, 2].map(|c| input.vertices[patch[9 + c] as usize])
        } else {
            own
        };
        let curves = [0, 1, 2].map(|e| edge_curve(input, patch, e, settings));
        let positions = own.map(|v| v.position);
        let surface = PnPatch::new(positions, [0, 1, 2].map(|e| curves[e].own_control_points()));
        let gradients = uv_gradients(positions, own.map(|v| v.uv));
        let (corner_lods, patch_lod) = match map {
            Some(map) => {
                let segment = settings.pixels_per_triangle * (1u32 << bias) as f32
                    / frame.view.pixels_per_unit
                    * frame.local_per_world();
                let corner_lods = dominant.map(|v| {
                    let world = frame.world_from_local.transform_point3(v.position);
                    let distance = if frame.view.orthographic == 1 {
                        1.0
                    } else {
                        (world - frame.view.position).length()
                    };
                    ((v.uv_density * map.size()).length() * segment * distance)
                        .max(1.0)
                        .log2()
                });
                let span = [0, 1, 2]
                    .map(|e| ((own[(e + 1) % 3].uv - own[e].uv) * map.size()).length())
                    .into_iter()
                    .fold(0.0f32, f32::max);
                (
                    corner_lods,
                    (span / (lod.factor * std::f32::consts::SQRT_2))
                        .max(1.0)
                        .log2(),
                )
            }
            None => ([0.0; 3], 0.0),
        };
        Self {
            input,
            settings,
            map,
            own,
            dominant,
            curves,
            surface,
            gradients,
            lod,
            corner_lods,
            patch_lod,
        }
    }

    fn displaced(&self, position: Vec3, direction: Vec3, uv: Vec2, lod: f32) -> Vec3 {
        match self.map {
            Some(map) => {
                let h = map.sample(uv, lod);
                position
                    + direction
                        * (self.settings.displacement_scale
                            * (h - self.settings.displacement_midlevel))
            }
            None => position,
        }
    }

    /// The shading normal at own barycentric `b`, bent by the height's slope.
    fn normal(&self, b: Vec3, lod: f32) -> Vec3 {
        let n = self.own.map(|v| v.normal);
        let base = match self.settings.mode {
            SurfaceMode::Flat => (n[0] * b.x + n[1] * b.y + n[2] * b.z).normalize_or_zero(),
            SurfaceMode::PnAen => pn_normal(self.own.map(|v| v.position), n, b),
        };
        match self.map {
            Some(map) => {
                let uv = self.own[0].uv * b.x + self.own[1].uv * b.y + self.own[2].uv * b.z;
                let slope = map.slope(uv, lod) * self.settings.displacement_scale;
                (base - (self.gradients.0 * slope.x + self.gradients.1 * slope.y))
                    .normalize_or_zero()
            }
            None => base,
        }
    }

    fn corner(&self, c: usize) -> OutVertex {
        let v = &self.dominant[c];
        let lod = self.corner_lods[c];
        let direction = if self.settings.crack_fixes {
            v.smooth_normal
        } else {
            v.normal
        };
        let bary = Vec3::AXES[c];
        OutVertex {
            position: self.displaced(v.position, direction, v.uv, lod),
            normal: self.normal(bary, lod),
            bary,
        }
    }

    /// Own barycentric of edge `e` at own parameter `t` (from corner `e`).
    fn edge_bary(e: usize, t: f32) -> Vec3 {
        let mut b = Vec3::ZERO;
        b[e] = 1.0 - t;
        b[(e + 1) % 3] = t;
        b
    }

    /// Vertex `x` of edge `e`'s own grid (level ℓ, canonical steps), unmorphed.
    fn edge_grid_point(&self, e: usize, x: u32, level: u32) -> OutVertex {
        let n = 1u32 << level;
        let curve = &self.curves[e];
        let (first, last) = if curve.reversed {
            ((e + 1) % 3, e)
        } else {
            (e, (e + 1) % 3)
        };
        if x == 0 {
            return self.corner(first);
        }
        if x == n {
            return self.corner(last);
        }
        let t = x as f32 / n as f32;
        let lod = match self.map {
            Some(map) => map.lod_for(curve.uv1 - curve.uv0, self.lod.edge_factors[e]),
            None => 0.0,
        };
        let (uv, direction) = curve.uv_and_direction(t);
        let position = self.displaced(curve.point(t, self.settings.mode), direction, uv, lod);
        let own_t = if curve.reversed { 1.0 - t } else { t };
        let bary = Self::edge_bary(e, own_t);
        OutVertex {
            position,
            normal: self.normal(bary, lod),
            bary,
        }
    }

    /// Vertex `x` of edge `e`'s own grid with the edge's morph.
    fn edge_point(&self, e: usize, x: u32) -> OutVertex {
        let (level, morph) = self.lod.edge_levels[e];
        let exact = self.edge_grid_point(e, x, level);
        if self.settings.partitioning == Partitioning::Integer || level == 0 || x.is_multiple_of(2)
        {
            return exact;
        }
        let a = self.edge_grid_point(e, x - 1, level);
        let b = self.edge_grid_point(e, x + 1, level);
        mix(a, b, exact, morph)
    }

    /// Grid vertex `(i, j)` of the patch (`n = 2^level`).
    fn grid_point(&self, n: u32, i: u32, j: u32) -> OutVertex {
        let k = n - i - j;
        match (i, j, k) {
            (0, 0, _) => self.corner(0),
            (_, 0, 0) => self.corner(1),
            (0, _, 0) => self.corner(2),
            (_, 0, _) => self.snapped(0, n, i),
            (_, _, 0) => self.snapped(1, n, j),
            (0, _, _) => self.snapped(2, n, k),
            _ => {
                let b = Vec3::new(k as f32, i as f32, j as f32) / n as f32;
                let p = self.own.map(|v| v.position);
                let position = match self.settings.mode {
                    SurfaceMode::Flat => p[0] * b.x + p[1] * b.y + p[2] * b.z,
                    SurfaceMode::PnAen => self.surface.point(b),
                };
                let uv = self.own[0].uv * b.x + self.own[1].uv * b.y + self.own[2].uv * b.z;
                let d = self.dominant.map(|v| {
                    if self.settings.crack_fixes {
                        v.smooth_normal
                    } else {
                        v.normal
                    }
                });
                let direction = (d[0] * b.x + d[1] * b.y + d[2] * b.z).normalize_or_zero();
                let position = self.displaced(position, direction, uv, self.patch_lod);
                OutVertex {
                    position,
                    normal: self.normal(b, self.patch_lod),
                    bary: b,
                }
            }
        }
    }

    /// The patch's grid vertex at own step `s` of edge `e`, snapped to the edge's grid.
    fn snapped(&self, e: usize, n: u32, s: u32) -> OutVertex {
        let level = n.trailing_zeros();
        let edge_level = self.lod.edge_levels[e].0;
        let d = level - edge_level.min(level);
        let canonical = if self.curves[e].reversed { n - s } else { s };
        let x = (canonical + ((1u32 << d) >> 1)) >> d;
        self.edge_point(e, x)
    }

    /// Grid vertex `(i, j)` of a patch with `n` segments.
    pub fn vertex(&self, n: u32, i: u32, j: u32) -> OutVertex {
        self.grid_point(n, i, j)
    }

    /// Texture coordinates and tangent at own barycentric `b`.
    pub fn attributes(&self, b: Vec3) -> (Vec2, Vec4) {
        let uv = self.own[0].uv * b.x + self.own[1].uv * b.y + self.own[2].uv * b.z;
        let t = self.own.map(|v| v.tangent);
        let xyz = (t[0].truncate() * b.x + t[1].truncate() * b.y + t[2].truncate() * b.z)
            .normalize_or_zero();
        (uv, xyz.extend(t[0].w))
    }

    /// The patch's levels.
    pub fn lod(&self) -> PatchLod {
        self.lod
    }

    /// The input the patch reads.
    pub fn input(&self) -> &TessellationInput {
        self.input
    }
}

/// The vertex between the midpoint of `a` and `b` (`morph` 0) and `exact` (1).
fn mix(a: OutVertex, b: OutVertex, exact: OutVertex, morph: f32) -> OutVertex {
    let mid = (a.position + b.position) * 0.5;
    let mid_normal = (a.normal + b.normal) * 0.5;
    OutVertex {
        position: mid + (exact.position - mid) * morph,
        normal: (mid_normal + (exact.normal - mid_normal) * morph).normalize_or_zero(),
        bary: exact.bary,
    }
}

/// Tessellates `input` for `frame` into at most `vertex_budget` vertices and
/// `index_budget` indices (factors halved until it fits).
pub fn tessellate(
    input: &TessellationInput,
    frame: &Frame,
    settings: &Settings,
    map: Option<&DisplacementMap>,
    vertex_budget: u64,
    index_budget: u64,
) -> TessellatedMesh {
    let factors: Vec<[f32; 3]> = input
        .patches
        .iter()
        .map(|patch| patch_edge_factors(input, patch, frame, settings))
        .collect();
    let levels = factors
        .iter()
        .map(|&f| patch_lod(f, 0, settings.partitioning).level.0);
    let bias = choose_bias(&demand(levels), vertex_budget, index_budget);
    let mut out = TessellatedMesh {
        bias,
        ..Default::default()
    };
    let mut grids: Vec<Vec<[u32; 3]>> = Vec::new();
    for (p, &f) in factors.iter().enumerate() {
        let lod = patch_lod(f, bias, settings.partitioning);
        let eval = PatchEval::new(input, p, frame, settings, map, lod, bias);
        let level = lod.level.0 as usize;
        while grids.len() <= level {
            grids.push(grid_triangles(1 << grids.len()));
        }
        let n = 1u32 << level;
        let base = out.positions.len() as u32;
        out.patches.push((base, out.indices.len() as u32, lod));
        for j in 0..=n {
            for i in 0..=n - j {
                debug_assert_eq!(grid_index(n, i, j), out.positions.len() as u32 - base);
                let v = eval.vertex(n, i, j);
                let (uv, tangent) = eval.attributes(v.bary);
                out.positions.push(v.position);
                out.normals.push(v.normal);
                out.uvs.push(uv);
                out.tangents.push(tangent);
            }
        }
        out.indices
            .extend(grids[level].iter().flatten().map(|&i| base + i));
    }
    out
}

impl PatchEval<'_> {
    /// The displacement mip of the patch's interior vertices.
    pub fn interior_mip(&self) -> f32 {
        self.patch_lod
    }
}
