//! The GPU parameters of distance-field shadows: one light as the shadow passes see it
//! ([`ShadowLight`], the `ShadowLight` uniform of `shaders/df/shadow.wgsl`) and the mask
//! pass's view ([`trace_view_words`], the `ShadowTraceView` uniform of
//! `shaders/df/shadow_trace.wgsl`). Byte layouts are checked against the WGSL by
//! `penumbra_shaders/tests/layout.rs`.

use crate::cull::CameraOrigin;
use glam::{Mat3, Mat4, UVec2, UVec4, Vec3};

mod thin_crossing;
pub use thin_crossing::{
    THIN_CROSSING_MAX_STRETCH, disc_slab, thin_crossing_ratio, thin_crossing_rim, visibility_ratio,
};

/// Bytes of the `ShadowLight` uniform.
pub const SHADOW_LIGHT_BYTES: usize = 64;
/// Bytes of the `ShadowGridView` uniform (`shaders/df/shadow_grid.wgsl`).
pub const SHADOW_GRID_VIEW_BYTES: usize = 64;
/// Bytes of the `ShadowGrid` storage buffer: bounds, large count, item count, height,
/// a reserved word, 1,024 cell counts and 1,025 offsets.
pub const SHADOW_GRID_BYTES: usize = 16 + 16 + 4 * 1024 + 4 * 1025;
/// Cells a caster may overlap before it is listed once as large.
pub const SHADOW_GRID_MAX_CELLS: usize = 64;
/// Bytes of the `ShadowTraceView` uniform.
pub const SHADOW_TRACE_VIEW_BYTES: usize = 64 + 48 + 16 + 16 + 16 + 16;

/// Where a shadowed light is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShadowLightKind {
    /// Unit vector toward the light.
    Directional(Vec3),
    /// Camera-relative position, metres (point and spot lights).
    Positional(Vec3),
}

/// One light as the shadow passes see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowLight {
    /// Where the light is.
    pub kind: ShadowLightKind,
    /// Point and spot lights: the source radius, metres. Directional lights: the tangent
    /// of half the angular diameter.
    pub source: f32,
    /// Directional lights: the shadow ray's length, metres.
    pub max_distance: f32,
    /// Start offset along the ray, metres (world-space bias).
    pub bias: f32,
    /// Penumbra shaping: visibility `v` becomes `v^shaping` (clamped to `[0.05, 20]`).
    pub shaping: f32,
    /// Point and spot lights: the range, metres (objects beyond it are culled).
    pub range: f32,
    /// Step limit per object.
    pub max_steps: u32,
    /// Directional lights: pixels farther than this from the camera, metres, are not
    /// traced (visibility 1), and casters that could shadow only such pixels are culled.
    /// Unused for point and spot lights (their range bounds them). Encoded as
    /// `max(0)`: NaN traces nothing.
    pub max_view_distance: f32,
    /// Spot lights: the unit direction the spot points (world axes) and the cosine of
    /// its outer angle. Pixels outside the cone (and, for point and spot lights, beyond
    /// `range`) receive none of the light and are not traced. `None`: no cone.
    pub spot: Option<(Vec3, f32)>,
}

impl ShadowLight {
    /// The uniform's 16 words.
    pub fn to_words(&self) -> [u32; SHADOW_LIGHT_BYTES / 4] {
        let (v, w) = match self.kind {
            ShadowLightKind::Directional(d) => (d, 0.0),
            ShadowLightKind::Positional(p) => (p, 1.0),
        };
        let f = f32::to_bits;
        // No cone: a cosine below −1 keeps every direction.
        let (spot, cos_outer) = self.spot.unwrap_or((Vec3::ZERO, -2.0));
        [
            f(v.x),
            f(v.y),
            f(v.z),
            f(w),
            f(self.source),
            f(self.max_distance),
            f(self.bias),
            f(self.shaping.clamp(0.05, 20.0)),
            f(self.range),
            self.max_steps,
            f(self.max_view_distance.max(0.0)),
            0,
            f(spot.x),
            f(spot.y),
            f(spot.z),
            f(cos_outer),
        ]
    }
}

/// Self-shadow offset of two-sided fields, in voxels beyond their shell: a receiver's
/// march through a two-sided (shell) field starts where its ray has risen
/// [`SHELL_VOXELS`] + this above the receiver's tangent plane (`rise / (n · l)`), at
/// most [`SELF_SHADOW_MAX_START_VOXELS`] voxels farther along the ray than it rises. A
/// two-sided bake puts a shell about √3/2 voxel thick about every surface, so a receiver
/// on the surface sits inside its own caster's field: a march that starts there reads
/// the shell as an occluder at every step until it rises out (blotches across a lit
/// terrain sheet or floor). Unreal's distance-field self-shadow bias, along the ray so
/// the cone and its culling are unchanged. Solid fields get none: their surface is the
/// zero crossing, and on the shadow bench's bunny half a voxel more lost 0.03 of
/// accuracy on its own creases (0.0476 → 0.0778); analytic shapes are exact.
pub const SELF_SHADOW_VOXELS: f32 = 0.5;

/// The shell a two-sided bake puts about every surface, voxels
/// (`penumbra_sdf::SignMethod::TWO_SIDED`).
pub const SHELL_VOXELS: f32 = 0.866_025_4;

/// How much farther than it rises a grazing ray's march may start, voxels.
pub const SELF_SHADOW_MAX_START_VOXELS: f32 = 4.0;

/// How far along the ray, in voxels of a field, a march through it may wait at most: a
/// field finer than the light's bias (a small prop: a 0.3 m lamp has 7 mm voxels under a
/// 4 cm bias) starts after this many of its own voxels instead, so its contact shadows
/// are not lost to a bias chosen for metre-scale fields. Coarser fields and analytic
/// shapes start at the bias. Chosen on the scene corpus (`tests/scene_corpus.rs`).
pub const FINE_FIELD_BIAS_VOXELS: f32 = 2.0;

/// How far outside a volume caster's surface a receiver may lie, in the field's voxels,
/// and still take the field's own normal for its own shadow: the surface's own shadow
/// (the light below its horizon) is decided by the caster's field where the G-buffer's
/// smooth or normal-mapped normal hides a light the triangles face
/// (`penumbra_reference::shadow_mask::field_normal`, `shadow.wgsl`'s `caster_field_normal`).
pub const FIELD_NORMAL_REACH_VOXELS: f32 = 1.0;

/// The field normal's gradient stencil (a tetrahedron of four samples), voxels from its
/// centre along each axis.
pub const FIELD_NORMAL_STEP_VOXELS: f32 = 0.5;

/// The field normal is kept only where its gradient's length is a distance's: within
/// these bounds (a sample stencil across a thin feature or a medial axis is not).
pub const FIELD_NORMAL_MIN_GRADIENT: f32 = 0.25;

/// See [`FIELD_NORMAL_MIN_GRADIENT`].
pub const FIELD_NORMAL_MAX_GRADIENT: f32 = 2.0;

/// The field's normal replaces the G-buffer's only where the two agree this well
/// (cosine): a normal map or smooth shading tilts a normal by less; a field read at a
/// sharp edge or across a thin part turns by more. Chosen on the scene corpus
/// (`tests/scene_corpus.rs`): 0.5 and 0.7 against facing 0.1–0.3 (CHANGELOG.md, #45).
pub const FIELD_NORMAL_MIN_AGREEMENT: f32 = 0.7;

/// ... and only where the field faces the light by at least this cosine, for a caster
/// whose shading normals are its faces' (no [`crate::object::flags::SHADING_APART`]: a
/// field normal is a voxel-scale estimate: within a few degrees of the terminator it
/// guessed the triangle's side wrong on the corpus; at 0.2 it lit facets of the shadow
/// bench's flat-shaded scanned bunny that its triangles turn away).
pub const FIELD_NORMAL_MIN_FACING: f32 = 0.3;

/// ... or by this cosine for a caster shaded apart from its faces (smooth vertex normals
/// or a normal map: [`crate::object::flags::SHADING_APART`]), whose G-buffer normals may
/// turn from a light its triangles face; the field normal's own horizon then shades the
/// receiver. Never where the depth buffer shows the G-buffer normal is the face's own
/// ([`FLAT_SHADED_SIN`]). From a sweep on the scene corpus (facing 0, 0.05, 0.1, 0.15,
/// 0.2, 0.3; CHANGELOG.md, #45) 0 gained most: a terrain's facets face a grazing sun by
/// 0.05–0.25 where its smooth normals turn away.
pub const FIELD_NORMAL_MIN_FACING_SHADED: f32 = 0.0;

/// A pixel's G-buffer normal is its face's own (flat-shaded, not smooth or normal-mapped)
/// where, along each screen axis, a neighbouring depth-buffer point lies in its tangent
/// plane within this sine (4°): `penumbra_reference::shadow_mask::flat_shaded`,
/// `shadow_trace.wgsl`'s `flat_shaded`.
pub const FLAT_SHADED_SIN: f32 = 0.07;

/// Where a receiver's G-buffer normal hides the light and neither it (a flat-shaded face,
/// [`FLAT_SHADED_SIN`]) nor a caster field gave the triangles' facing, on a caster shaded
/// apart from its faces ([`crate::object::flags::SHADING_APART`]) or on no caster field
/// (on a flat-shaded caster it took the shadow bench's scanned bunny 0.0318 → 0.0380:
/// pixel-sized facets whose G-buffer normals are their faces'), the depth buffer
/// does: the face normal through the pixel's neighbours (per screen axis the central
/// difference of the two, or the one's), trusted only where every neighbour on a surface
/// lies within this sine (11.5°) of its plane — not across a crease or a silhouette —
/// and where it agrees with the G-buffer normal by at least [`FACE_NORMAL_MIN_AGREEMENT`]
/// (a smooth or normal-mapped normal a little past the terminator of facets that face the
/// light: ray tracing lights them). Then the face normal's own horizon shades the
/// receiver. Sweep on the scene corpus (agreement 0.9, a first one-sided estimator; the
/// central differences gave the same lamp figure; CHANGELOG.md, #45): no plane test
/// 0.155 / 0.079 on the barn lamp / flight helmet, 0.2 gave 0.168 / 0.075, 0.1 0.175 /
/// 0.075, 0.05 0.189 / 0.076 (before: 0.201 / 0.075); the others unchanged.
pub const FACE_NORMAL_PLANE_SIN: f32 = 0.2;

/// ... and where the depth buffer's face normal agrees with the G-buffer normal by at
/// least this cosine (25°). Sweep (one-sided, facing 0.05, no plane test): 0.8 took the cake
/// 0.044 → 0.065 and the helmet to 0.086 (normals across its slices' seams); 0.95 kept
/// too little (lamp 0.163).
pub const FACE_NORMAL_MIN_AGREEMENT: f32 = 0.9;

/// Where the view has the face-normal prepass (`bevy_penumbra_df::face_normals`), a
/// pixel's triangle normal is trusted where the prepass drew the same surface the
/// G-buffer holds: its reverse-Z depth within this fraction of the G-buffer's (the
/// same triangles rasterised twice agree to a few ulps; an alpha-masked cut-out, a
/// culled back face or a material's own vertex displacement differ by far more). Then that normal,
/// turned to face the eye, alone gives the receiver's own shadow, as a ray tracer's
/// triangle does, and the march leaves along it.
pub const FACE_DEPTH_TOLERANCE: f32 = 1.0e-3;

/// Whether the face-normal prepass's pixel (its reverse-Z `face_depth`, its target's
/// `drawn` flag) holds the surface the G-buffer's reverse-Z `depth` does
/// ([`FACE_DEPTH_TOLERANCE`]; `shadow_trace.wgsl`'s `pixel_face_normal`).
pub fn face_normal_trusted(drawn: bool, face_depth: f32, depth: f32) -> bool {
    depth > 0.0 && drawn && (face_depth - depth).abs() <= FACE_DEPTH_TOLERANCE * depth
}

/// `ShadowTraceView`'s input bits (`size.w`): the G-buffer binding holds the view's
/// normals.
pub const TRACE_GBUFFER_NORMALS: u32 = 1;
/// ... the face-normal bindings hold the view's face-normal prepass.
pub const TRACE_FACE_NORMALS: u32 = 2;

/// A receiver sees a solid volume caster from its inside — the back of an open surface
/// baked solid: a terrain's or floor's underside at its cut edge, seen by a camera below
/// its rim, the inside of an open shell closed by the winding number — where the field,
/// read [`FROM_INSIDE_PROBE_VOXELS`] voxels along its G-buffer normal (turned to face the
/// eye), lies at least this many voxels inside ([`seen_from_inside`]). A visible surface's
/// own side is never inside a solid: that caster is not marched for the receiver, and
/// its field's normal, reversed, gives the receiver's own shadow (the triangles' back
/// face; the truth's sheet has no thickness, the field's solid does).
pub const FROM_INSIDE_MIN_DEPTH_VOXELS: f32 = 0.25;

/// The probes' distance from the receiver along its normal, in the field's voxels
/// ([`seen_from_inside`]).
pub const FROM_INSIDE_PROBE_VOXELS: f32 = 1.0;

/// ... and where the field falls by at least this many voxels from the probe behind
/// the receiver to the probe in front of it: the field deepens toward the eye. A floor
/// receiver beside a solid box standing on it reads the box's field falling upward too
/// (below the floor lies farther from the box) but outside it, so the depth test keeps it.
pub const FROM_INSIDE_MIN_DROP_VOXELS: f32 = 0.5;

/// ... and only where the receiver lies on the field's surface, within this many voxels:
/// a floor under a caster's overhang closer than a voxel (the Stanford bunny's belly)
/// reads the caster's field inside in front of it and deeper than behind it too, but
/// lies off its surface by the gap (without this, the shadow bench's bunny lost contact
/// shadows under its belly: 0.0314 → 0.0338).
pub const FROM_INSIDE_ON_SURFACE_VOXELS: f32 = 0.25;

/// Whether a receiver sees a solid field of voxel size `voxel` from its inside, from the
/// field's distances `at` the receiver and `front` and `back` read
/// [`FROM_INSIDE_PROBE_VOXELS`] voxels in front of it (along its normal, toward the eye)
/// and behind it ([`FROM_INSIDE_ON_SURFACE_VOXELS`], [`FROM_INSIDE_MIN_DEPTH_VOXELS`],
/// [`FROM_INSIDE_MIN_DROP_VOXELS`]; NaN: no). `shadow.wgsl`'s `seen_from_inside`.
pub fn seen_from_inside(at: f32, front: f32, back: f32, voxel: f32) -> bool {
    voxel > 0.0
        && at.abs() <= FROM_INSIDE_ON_SURFACE_VOXELS * voxel
        && front <= -FROM_INSIDE_MIN_DEPTH_VOXELS * voxel
        && front - back <= -FROM_INSIDE_MIN_DROP_VOXELS * voxel
}

/// A triangle corner whose vertex normal turns from its face's by more than this cosine
/// (5°) is shaded apart from it.
pub const SHADING_APART_COS: f32 = 0.996;

/// A mesh is shaded apart from its faces ([`crate::object::flags::SHADING_APART`]) when
/// at least this share of its triangles' corners is ([`SHADING_APART_COS`]).
pub const SHADING_APART_SHARE: f32 = 0.1;

/// Whether a mesh's vertex `normals` turn from its triangles' faces (smooth shading: a
/// sphere, a terrain, a character) rather than being them (flat shading: a box, a
/// low-poly prop): at least [`SHADING_APART_SHARE`] of the non-degenerate triangles'
/// corners turn by more than [`SHADING_APART_COS`] from the face (either side: a normal
/// against the winding is the face's too). `triangles` index `positions` and `normals`;
/// indices out of range and non-finite corners are skipped; `false` without any.
pub fn shading_apart_from_faces(
    positions: &[Vec3],
    normals: &[Vec3],
    triangles: impl IntoIterator<Item = [u32; 3]>,
) -> bool {
    let (mut apart, mut corners) = (0u64, 0u64);
    for tri in triangles {
        let Some(p) = tri
            .map(|i| positions.get(i as usize).copied())
            .into_iter()
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if face == Vec3::ZERO {
            continue;
        }
        for i in tri {
            let Some(n) = normals.get(i as usize).map(|n| n.normalize_or_zero()) else {
                continue;
            };
            if n == Vec3::ZERO {
                continue;
            }
            corners += 1;
            if face.dot(n).abs() < SHADING_APART_COS {
                apart += 1;
            }
        }
    }
    corners > 0 && apart as f64 >= f64::from(SHADING_APART_SHARE) * corners as f64
}

/// The least step of a shadow march inside an occluder, in radii of the light's cone
/// where it is: a march goes on through a solid occluder (distances below 0) until the
/// cone is covered ([`penumbra_step`]).
///
/// **The penumbra is two-sided.** A march keeps the least ratio `d / r` of the distance
/// to the nearest surface and the cone's radius, down to −1 (the cone's axis a radius
/// inside), and the light's visible fraction is its smoothstep from −1 to 1
/// ([`penumbra_visibility`]): ½ where the axis grazes a silhouette, as a disc half
/// covered, instead of 0 — Quílez's improved soft shadow, which lets the penumbra
/// reach into the geometric shadow. The one-sided form (`d / r` stopped at the first
/// surface, 0 from there) darkened every penumbra's inner half; its shaping exponent
/// (0.325) only bent it back. Inside a thin part (a leaf, a wall) the distance says
/// nothing of how far the part reaches across the cone: a ray that leaves through the
/// face opposite the one it entered by ([`THIN_CROSSING_COSINE`]) finds the cone covered
/// as far as the part reaches across it ([`thin_crossing_ratio`]), and any ray entering a
/// two-sided shell finds it covered, as the one-sided march did.
pub const PENUMBRA_MIN_STEP: f32 = 0.25;

/// A march outside an occluder steps at least this many of a field's voxels (and at
/// most [`PENUMBRA_MIN_STEP`] cone radii; a hundredth of a radius for an analytic
/// shape), so that it crosses a surface it approaches at an angle instead of creeping up
/// to it, without stepping over a part a voxel thick.
pub const SURFACE_STEP_VOXELS: f32 = 0.25;

/// A ray through a solid part crossed a thin part, not a silhouette, where the surface
/// normals where it went in and where it came out (the field's gradients at the last
/// sample before and the first after) meet at a cosine below this: opposite faces of a
/// leaf or a wall (−1), not a silhouette's grazing chord (about 1) or a box's corner (0).
pub const THIN_CROSSING_COSINE: f32 = -0.5;

/// One step of the two-sided penumbra's march, where the distance is `d` and the cone's
/// radius `cone`, through a field of world voxel size `voxel` (0: an analytic shape),
/// `two_sided` a shell. `entered` is the surface normal where the ray went inside
/// (`None` outside; kept between steps); `normal_before` gives it at the previous sample
/// and `normal_here` at this one (called only on the step in and the step out). Returns
/// the ratio the step leaves (`d / cone`; −1 where the cone is covered: a shell entered;
/// where a thin part was crossed, what `thin` gives for the entry normal:
/// [`thin_crossing_ratio`] of the field at [`thin_crossing_rim`]) and how far to step
/// (0: stop, covered).
#[allow(clippy::too_many_arguments, reason = "one step's inputs")]
pub fn penumbra_step(
    d: f32,
    cone: f32,
    voxel: f32,
    two_sided: bool,
    entered: &mut Option<Vec3>,
    normal_before: impl FnOnce() -> Vec3,
    normal_here: impl FnOnce() -> Vec3,
    thin: impl FnOnce(Vec3) -> f32,
) -> (f32, f32) {
    if d <= 0.0 {
        if two_sided {
            return (-1.0, 0.0);
        }
        if entered.is_none() {
            *entered = Some(normal_before());
        }
        return (d / cone, (-d).max(cone * PENUMBRA_MIN_STEP));
    }
    if let Some(normal_in) = entered.take()
        && normal_in.dot(normal_here()) < THIN_CROSSING_COSINE
    {
        let ratio = thin(normal_in);
        if ratio <= -1.0 {
            return (-1.0, 0.0);
        }
        return (ratio, d.max(surface_step(cone, voxel)));
    }
    (d / cone, d.max(surface_step(cone, voxel)))
}

/// The least step outside an occluder ([`SURFACE_STEP_VOXELS`]).
pub fn surface_step(cone: f32, voxel: f32) -> f32 {
    if voxel > 0.0 {
        (SURFACE_STEP_VOXELS * voxel).min(cone * PENUMBRA_MIN_STEP)
    } else {
        0.01 * cone
    }
}

/// The gradient stencil of [`penumbra_step`]'s normals: half a voxel, or a twentieth of
/// the cone's radius for an analytic shape.
pub fn crossing_stencil(cone: f32, voxel: f32) -> f32 {
    if voxel > 0.0 {
        0.5 * voxel
    } else {
        0.05 * cone
    }
}

/// The gradient of a distance `d` at `q` from a tetrahedron of four samples `s` from it
/// along each axis, and the samples' mean (`shadow.wgsl`'s `tetrahedral_distances` and
/// `tetrahedral_gradient`).
pub fn tetrahedral_gradient(q: Vec3, s: f32, mut d: impl FnMut(Vec3) -> f32) -> (Vec3, f32) {
    let ks = [
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(-1.0, -1.0, 1.0),
        Vec3::new(-1.0, 1.0, -1.0),
        Vec3::new(1.0, 1.0, 1.0),
    ];
    let ds = ks.map(|k| d(q + k * s));
    let g = (ks[0] * ds[0] + ks[1] * ds[1] + ks[2] * ds[2] + ks[3] * ds[3]) / (4.0 * s);
    (g, 0.25 * (ds[0] + ds[1] + ds[2] + ds[3]))
}

/// The unit normal of a distance `d` at `q` ([`tetrahedral_gradient`]; zero where the
/// gradient vanishes).
pub fn tetrahedral_normal(q: Vec3, s: f32, d: impl FnMut(Vec3) -> f32) -> Vec3 {
    tetrahedral_gradient(q, s, d).0.normalize_or_zero()
}

/// The fraction of a light's disc left open where a march's least `d / r` (distance to
/// the nearest surface over the cone's radius, [`PENUMBRA_MIN_STEP`]) is `x`: the
/// smoothstep from −1 (covered) to 1 (open). `shadow.wgsl`'s `penumbra_visibility`.
pub fn penumbra_visibility(x: f32) -> f32 {
    let x = if x.is_nan() { -1.0 } else { x.clamp(-1.0, 1.0) };
    0.25 * (1.0 + x) * (1.0 + x) * (2.0 - x)
}

/// Where a march through a field of world voxel size `voxel` (0: an analytic shape)
/// starts along the ray from a receiver of unit normal `normal` (zero: unknown) under a
/// light of world bias `bias`: the bias, or [`FINE_FIELD_BIAS_VOXELS`] voxels of a finer
/// field, and past a two-sided field's own shell ([`self_shadow_start`]).
/// `shadow.wgsl`'s `march_start`.
pub fn march_start(bias: f32, voxel: f32, two_sided: bool, normal: Vec3, dir: Vec3) -> f32 {
    let bias = if voxel > 0.0 && voxel.is_finite() {
        bias.min(FINE_FIELD_BIAS_VOXELS * voxel)
    } else {
        bias
    };
    bias.max(self_shadow_start(voxel, two_sided, normal, dir))
}

/// Where a march through a field of world voxel size `voxel` starts along the ray for a
/// receiver of unit normal `normal` (zero: unknown, no offset) and ray direction `dir`:
/// 0 unless the field is `two_sided` (`shadow.wgsl`'s `self_shadow_start`).
pub fn self_shadow_start(voxel: f32, two_sided: bool, normal: Vec3, dir: Vec3) -> f32 {
    if !two_sided || voxel.is_nan() || voxel <= 0.0 || normal == Vec3::ZERO {
        return 0.0;
    }
    let rise = (SHELL_VOXELS + SELF_SHADOW_VOXELS) * voxel;
    let most = rise + SELF_SHADOW_MAX_START_VOXELS * voxel;
    (rise / normal.dot(dir).max(1e-3)).min(most)
}

/// The `ShadowTraceView` uniform: the camera's `view_from_clip` (inverse projection),
/// its world-from-view rotation (camera-relative positions need no translation), its
/// tile origin, the mask size and its stride (`1`: full resolution; `2`: half, texel
/// `(i, j)` traces pixel `(2i, 2j)`), which normals the pass's bindings hold
/// ([`TRACE_GBUFFER_NORMALS`], [`TRACE_FACE_NORMALS`]), and how many terrains
/// (heightfield records bound) each pixel also marches (the tile word's `w`), and the
/// view's viewport in the frame buffer (`x, y, width, height`, full-resolution pixels:
/// the prepass textures are the render target's size, the mask the viewport's).
#[allow(clippy::too_many_arguments, reason = "one uniform's fields")]
pub fn trace_view_words(
    view_from_clip: Mat4,
    world_from_view: Mat3,
    camera: &CameraOrigin,
    size: UVec2,
    stride: u32,
    inputs: u32,
    heightfields: u32,
    viewport: UVec4,
) -> Vec<u32> {
    let mut words = Vec::with_capacity(SHADOW_TRACE_VIEW_BYTES / 4);
    words.extend(view_from_clip.to_cols_array().map(f32::to_bits));
    for c in [
        world_from_view.x_axis,
        world_from_view.y_axis,
        world_from_view.z_axis,
    ] {
        words.extend(c.extend(0.0).to_array().map(f32::to_bits));
    }
    words.extend([
        camera.tile[0] as u32,
        camera.tile[1] as u32,
        camera.tile[2] as u32,
        heightfields,
    ]);
    words.extend(camera.offset.extend(0.0).to_array().map(f32::to_bits));
    words.extend([size.x, size.y, stride.max(1), inputs]);
    words.extend(viewport.to_array());
    words
}

/// Little-endian bytes of words.
pub fn words_to_bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// Size of a half-resolution mask for a `full`-size view: one texel per 2×2 pixels
/// (rounded up).
pub fn half_size(full: UVec2) -> UVec2 {
    UVec2::new(full.x.div_ceil(2), full.y.div_ceil(2))
}

/// The `ShadowGridView` uniform: the camera's tile origin and light-space axes `u`, `v`
/// (unit, perpendicular to `to_light` and to each other); `u.w` = 1 when the mask pass
/// is to use the grid.
pub fn grid_view_words(camera: &CameraOrigin, to_light: Vec3, enabled: bool) -> Vec<u32> {
    let l = to_light.try_normalize().unwrap_or(Vec3::Y);
    let helper = if l.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let u = l.cross(helper).normalize();
    let v = l.cross(u);
    let mut words = Vec::with_capacity(SHADOW_GRID_VIEW_BYTES / 4);
    words.extend([
        camera.tile[0] as u32,
        camera.tile[1] as u32,
        camera.tile[2] as u32,
        0,
    ]);
    words.extend(camera.offset.extend(0.0).to_array().map(f32::to_bits));
    words.extend(
        u.extend(if enabled { 1.0 } else { 0.0 })
            .to_array()
            .map(f32::to_bits),
    );
    words.extend(v.extend(0.0).to_array().map(f32::to_bits));
    words
}

#[cfg(test)]
mod tests;
