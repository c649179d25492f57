//! Deferred MSAA's edge test (`shaders/lighting/msaa.wgsl`): its thresholds, shared by
//! the shader (by `encase`) and the CPU model (`penumbra_reference::msaa`).

use encase::ShaderType;

/// When a pixel's samples differ (it is shaded per sample).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct EdgeParams {
    /// Samples may differ in view depth by this many times the pixel's depth slope
    /// (`|∂z/∂x| + |∂z/∂y|`). Default 1: every sample lies within a pixel of sample 0
    /// in x and in y.
    pub slope_scale: f32,
    /// …plus this fraction of sample 0's depth (storage and derivative precision).
    /// Default 10⁻³.
    pub relative_depth: f32,
    /// Samples whose normals' cosine with sample 0's falls below this differ. Default
    /// 0.98 (11.5°).
    pub normal_cos: f32,
    /// Samples per pixel compared (1–4).
    pub sample_count: u32,
}

impl Default for EdgeParams {
    fn default() -> Self {
        Self {
            slope_scale: 1.0,
            relative_depth: 1e-3,
            normal_cos: 0.98,
            sample_count: 4,
        }
    }
}
