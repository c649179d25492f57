//! The CPU reference tessellator: the GPU passes' model (`shaders/tessellation/`), vertex
//! for vertex, and the measurements the tests and benches take of its output.

use super::factors::{TessellationView, biased, choose_bias, demand, edge_factor};
use super::layout::{self, Counts, Place, position};
use super::patch::{DisplacementMap, EdgeCurve, PnPatch, edge_curve, pn_normal, uv_gradients};
use super::preprocess::{TessVertex, TessellationInput};
use super::{Settings, SurfaceMode};
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

/// A patch's factors and segment counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchLod {
    /// Each edge's factor after the bias.
    pub edge_factors: [f32; 3],
    /// The inside factor (the largest edge's).
    pub factor: f32,
    /// Segments per edge and inside.
    pub counts: Counts,
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

/// The patch's factors and counts after `bias`.
pub fn patch_lod(factors: [f32; 3], bias: u32) -> PatchLod {
    let edge_factors = factors.map(|f| biased(f, bias));
    PatchLod {
        edge_factors,
        factor: edge_factors[0].max(edge_factors[1]).max(edge_factors[2]),
        counts: Counts::new(edge_factors),
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
                // The mean of the edges' texel spans: a tessellated edge covers about
                // one texel of the mip (the longest edge's a little more).
                let span = [0, 1, 2]
                    .map(|e| ((own[(e + 1) % 3].uv - own[e].uv) * map.size()).length())
                    .into_iter()
                    .fold(0.0f32, |sum, s| sum + s)
                    / 3.0;
                (corner_lods, (span / lod.factor).max(1.0).log2())
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

    /// Edge `e`'s vertex `x` in its canonical order (0 and `nₑ`: its corners).
    fn edge_point(&self, e: usize, x: u32) -> OutVertex {
        let n = self.lod.counts.edges[e];
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
        let t = position(self.lod.edge_factors[e], n, x, self.settings.partitioning);
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

    /// Edge `e`'s own parameter of its vertex `j` from corner `e`.
    pub fn edge_t(&self, e: usize, j: u32) -> f32 {
        let n = self.lod.counts.edges[e];
        if self.curves[e].reversed {
            1.0 - position(
                self.lod.edge_factors[e],
                n,
                n - j,
                self.settings.partitioning,
            )
        } else {
            position(self.lod.edge_factors[e], n, j, self.settings.partitioning)
        }
    }

    /// The patch's surface at own barycentric `b`, displaced.
    fn inside_point(&self, b: Vec3) -> OutVertex {
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

    /// Local vertex `v` of the patch.
    pub fn vertex(&self, v: u32) -> OutVertex {
        match layout::place(
            &self.lod.counts,
            self.lod.factor,
            self.settings.partitioning,
            v,
        ) {
            Place::Edge { e, j: 0 } => self.corner(e),
            Place::Edge { e, j } => {
                let n = self.lod.counts.edges[e];
                self.edge_point(e, if self.curves[e].reversed { n - j } else { j })
            }
            Place::Inside(b) => self.inside_point(b),
        }
    }

    /// Local triangle `t` of the patch.
    pub fn triangle(&self, t: u32) -> [u32; 3] {
        layout::triangle(
            &self.lod.counts,
            self.lod.factor,
            self.settings.partitioning,
            &|e, j| self.edge_t(e, j),
            t,
        )
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
    let bias = choose_bias(
        &demand(factors.iter().copied()),
        vertex_budget,
        index_budget,
    );
    let mut out = TessellatedMesh {
        bias,
        ..Default::default()
    };
    for (p, &f) in factors.iter().enumerate() {
        let lod = patch_lod(f, bias);
        let eval = PatchEval::new(input, p, frame, settings, map, lod, bias);
        let base = out.positions.len() as u32;
        out.patches.push((base, out.indices.len() as u32, lod));
        for v in 0..lod.counts.vertices() {
            let vertex = eval.vertex(v);
            let (uv, tangent) = eval.attributes(vertex.bary);
            out.positions.push(vertex.position);
            out.normals.push(vertex.normal);
            out.uvs.push(uv);
            out.tangents.push(tangent);
        }
        for t in 0..lod.counts.triangles() {
            out.indices.extend(eval.triangle(t).map(|i| base + i));
        }
    }
    out
}

impl PatchEval<'_> {
    /// The displacement mip of the patch's inside vertices.
    pub fn interior_mip(&self) -> f32 {
        self.patch_lod
    }
}
