//! The global field's debug views (`shaders/df/global_field_debug.wgsl`): their uniform
//! and the bits of the bricks composed this frame. Model:
//! `penumbra_reference::field_debug`.

use super::{BRICK_WORDS, ClipmapLayout, ComposeJob};
use encase::ShaderType;
use glam::Mat4;

/// What a global-field debug view shows (the `mode` of [`FieldDebugParams`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum FieldDebugMode {
    /// The field's surfaces, sphere-traced, Lambert-shaded.
    Shaded = 0,
    /// The same, tinted by the clipmap level that answered ([`LEVEL_COLORS`]).
    Levels = 1,
    /// The same, bricks composed this frame in orange.
    Updates = 2,
}

/// The colour of each clipmap level in [`FieldDebugMode::Levels`] (linear RGB): red,
/// orange, yellow, green, cyan, blue, violet, magenta — finest first.
pub const LEVEL_COLORS: [[f32; 3]; 8] = [
    [1.0, 0.25, 0.2],
    [1.0, 0.6, 0.1],
    [0.95, 0.95, 0.2],
    [0.3, 0.9, 0.3],
    [0.2, 0.85, 0.9],
    [0.25, 0.4, 1.0],
    [0.6, 0.3, 1.0],
    [1.0, 0.3, 0.85],
];

/// The debug view's uniform (`FieldDebugParams` in the shader).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct FieldDebugParams {
    /// Camera-relative world position of a point on a pixel's ray from clip space.
    pub relative_from_clip: Mat4,
    /// [`FieldDebugMode`] as a number.
    pub mode: u32,
    /// Sphere-tracing step limit.
    pub max_steps: u32,
    /// Trace length, metres.
    pub max_distance: f32,
}

/// Bits of the storage bricks `jobs` write, laid out as the validity bits
/// (`GlobalFieldView::valid_bits`: level after level, `valid_words` words each).
pub fn composed_bits<'a>(
    layout: &ClipmapLayout,
    jobs: impl IntoIterator<Item = &'a ComposeJob>,
) -> Vec<u32> {
    let per_level = layout.bricks_per_level();
    let words_per_level = per_level.div_ceil(32);
    let mut bits = vec![0u32; (words_per_level * layout.levels) as usize];
    for job in jobs {
        let brick = job.word / BRICK_WORDS - job.level * per_level;
        bits[(job.level * words_per_level + brick / 32) as usize] |= 1 << (brick % 32);
    }
    bits
}
