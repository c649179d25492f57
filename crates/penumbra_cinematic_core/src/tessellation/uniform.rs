//! What the tessellation passes share with the CPU (`penumbra::tessellation::patch`).

use super::factors::TessellationView;
use super::patch::{DisplacementMap, MAX_DISPLACEMENT_LEVELS};
use super::reference::Frame;
use super::{Partitioning, Settings, SurfaceMode};
use encase::ShaderType;
use glam::{Mat4, UVec4, Vec2};

/// Bytes of one patch's state (`PatchState`: factors, level, first vertex and index,
/// output level).
pub const PATCH_STATE_BYTES: u64 = 32;

/// Bytes of the totals (`Totals`: bias, vertices, indices, patches, the vertices and
/// indices asked for at bias 0, two reserved words).
pub const TOTALS_BYTES: u64 = 32;

/// One tessellated entity's uniform.
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct TessellationUniform {
    /// The mesh's transform.
    pub world_from_local: Mat4,
    /// The camera the factors are for.
    pub view: TessellationView,
    /// [`Settings::pixels_per_triangle`].
    pub pixels_per_triangle: f32,
    /// [`Settings::max_level`].
    pub max_level: u32,
    /// 0 flat, 1 PN-AEN.
    pub mode: u32,
    /// 0 integer, 1 fractional.
    pub partitioning: u32,
    /// [`Settings::crack_fixes`].
    pub crack_fixes: u32,
    /// [`Settings::displacement_scale`].
    pub displacement_scale: f32,
    /// [`Settings::displacement_midlevel`].
    pub displacement_midlevel: f32,
    /// [`Frame::local_per_world`].
    pub local_per_world: f32,
    /// Level 0's size in texels (zero without a map).
    pub map_size: Vec2,
    /// Levels in the map (0 without one).
    pub map_levels: u32,
    /// Patches.
    pub patch_count: u32,
    /// Output vertices the pool holds.
    pub vertex_budget: u32,
    /// Output indices the pool holds.
    pub index_budget: u32,
    /// `f32` words per output vertex (8, or 12 with tangents).
    pub vertex_words: u32,
    /// 1 when the output has tangents.
    pub has_tangents: u32,
    /// Per map level: width, height, first texel.
    pub map_level_info: [UVec4; MAX_DISPLACEMENT_LEVELS],
}

impl TessellationUniform {
    /// The uniform of `settings` for `frame`.
    #[allow(clippy::too_many_arguments, reason = "each is a separate input")]
    pub fn new(
        frame: &Frame,
        settings: &Settings,
        map: Option<&DisplacementMap>,
        patch_count: u32,
        vertex_budget: u32,
        index_budget: u32,
        has_tangents: bool,
    ) -> Self {
        let mut map_level_info = [UVec4::ZERO; MAX_DISPLACEMENT_LEVELS];
        if let Some(map) = map {
            for (info, &[w, h, offset]) in map_level_info.iter_mut().zip(&map.levels) {
                *info = UVec4::new(w, h, offset, 0);
            }
        }
        Self {
            world_from_local: frame.world_from_local,
            view: frame.view,
            pixels_per_triangle: settings.pixels_per_triangle,
            max_level: settings.max_level,
            mode: (settings.mode == SurfaceMode::PnAen) as u32,
            partitioning: (settings.partitioning == Partitioning::Fractional) as u32,
            crack_fixes: settings.crack_fixes as u32,
            displacement_scale: settings.displacement_scale,
            displacement_midlevel: settings.displacement_midlevel,
            local_per_world: frame.local_per_world(),
            map_size: map.map_or(Vec2::ZERO, DisplacementMap::size),
            map_levels: map.map_or(0, |m| m.levels.len() as u32),
            patch_count,
            vertex_budget,
            index_budget,
            vertex_words: if has_tangents { 12 } else { 8 },
            has_tangents: has_tangents as u32,
            map_level_info,
        }
    }
}
