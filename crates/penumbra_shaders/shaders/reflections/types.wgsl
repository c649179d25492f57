// Billboard reflections' structs shared with the Rust encoders (no bindings): used by
// `reflections/common.wgsl` and the caster spheres' pass (`reflections/spheres.wgsl`).
#define_import_path penumbra::reflections::types

// `penumbra_cinematic_core::reflections::pass::GpuBillboard`.
struct GpuBillboard {
    center: vec3<f32>,
    layer: u32,
    half_x: vec3<f32>,
    emissive: f32,
    half_y: vec3<f32>,
    // Render-layer groups (`GpuBillboard::layers`): a view reflects it where they meet
    // `ReflectionUniform::view_layers`.
    layers: u32,
}

// `penumbra_cinematic_core::reflections::pass::ReflectionUniform`.
struct ReflectionUniform {
    billboard_count: u32,
    max_layers: u32,
    max_distance: f32,
    anisotropy: f32,
    texture_size: vec2<u32>,
    mip_count: u32,
    half_resolution: u32,
    camera_tile: vec3<i32>,
    object_count: u32,
    camera_offset: vec3<f32>,
    footprint_slope: f32,
    shadow_steps: u32,
    shadow_bias: f32,
    shadow_softness: f32,
    taps: u32,
    // Tiles per row of the trace's image; billboards a tile's list holds (0: no lists,
    // the trace tests every billboard).
    tiles_x: u32,
    tile_capacity: u32,
    // The trace's image size, pixels.
    trace_size: vec2<u32>,
    // The shadow cone's half-width as a share of the footprint's long half-axis.
    shadow_cone: f32,
    // Shadow casters a tile's list holds (0: no caster lists).
    caster_capacity: u32,
    // The render-layer groups the view sees.
    view_layers: u32,
}
