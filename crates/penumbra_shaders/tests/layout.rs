//! The WGSL view of GPU data and the Rust encoders agree: struct sizes and member
//! offsets, and every shared constant.

use naga::{Expression, Literal, Module, TypeInner};
use penumbra_df_core::object::{RECORD_BYTES, ShapeKind, TILE_SIZE, flags};
use penumbra_shaders::flatten;

fn parse(source: &str) -> Module {
    let wgsl = flatten(source).expect("flatten");
    naga::front::wgsl::parse_str(&wgsl).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&wgsl)))
}

/// `(member name, byte offset)` of a struct, and its size.
fn struct_layout(module: &Module, name: &str) -> (Vec<(String, u32)>, u32) {
    for (_, ty) in module.types.iter() {
        if ty.name.as_deref() == Some(name)
            && let TypeInner::Struct { members, span } = &ty.inner
        {
            let m = members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect();
            return (m, *span);
        }
    }
    panic!("no struct {name}");
}

/// The value of a scalar `const` as f64.
fn constant(module: &Module, name: &str) -> f64 {
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no const {name}"));
    match module.global_expressions[c.init] {
        Expression::Literal(Literal::U32(v)) => v as f64,
        Expression::Literal(Literal::I32(v)) => v as f64,
        Expression::Literal(Literal::F32(v)) => v as f64,
        Expression::Literal(Literal::AbstractInt(v)) => v as f64,
        Expression::Literal(Literal::AbstractFloat(v)) => v,
        ref e => panic!("{name}: not a literal: {e:?}"),
    }
}

#[test]
fn object_record_layout_matches_the_encoder() {
    let m = parse("#import penumbra::df::object\n");
    let (members, size) = struct_layout(&m, "DistanceFieldObject");
    assert_eq!(size as usize, RECORD_BYTES);
    // Word offsets documented in penumbra_df_core::object (× 4 bytes).
    let want = [
        ("shape_from_world", 0),
        ("world_from_shape", 12),
        ("tile", 24),
        ("flags", 27),
        ("params", 28),
        ("conservative_scale", 31),
    ];
    let got: Vec<(&str, u32)> = members.iter().map(|(n, o)| (n.as_str(), *o)).collect();
    let want: Vec<(&str, u32)> = want.iter().map(|&(n, w)| (n, w * 4)).collect();
    assert_eq!(got, want);
}

#[test]
fn shared_constants_match() {
    let m = parse("#import penumbra::df::object\n");
    let cases = [
        ("TILE_SIZE", TILE_SIZE as f64),
        ("FLAG_CASTS_SHADOWS", flags::CASTS_SHADOWS as f64),
        ("FLAG_CASTS_OCCLUSION", flags::CASTS_OCCLUSION as f64),
        ("FLAG_TWO_SIDED", flags::TWO_SIDED as f64),
        ("FLAG_VISIBLE", flags::VISIBLE as f64),
        ("FLAG_UNBOUNDED", flags::UNBOUNDED as f64),
        ("FLAG_LIVE", flags::LIVE as f64),
        ("FLAG_CAST_HIDDEN_SHADOW", flags::CAST_HIDDEN_SHADOW as f64),
        ("FLAG_BRICKED", flags::BRICKED as f64),
        ("KIND_SHIFT", flags::KIND_SHIFT as f64),
        ("KIND_MASK", flags::KIND_MASK as f64),
        ("KIND_VOLUME", ShapeKind::Volume as u32 as f64),
        ("KIND_SPHERE", ShapeKind::Sphere as u32 as f64),
        ("KIND_CUBOID", ShapeKind::Cuboid as u32 as f64),
        ("KIND_CAPSULE", ShapeKind::Capsule as u32 as f64),
        ("KIND_PLANE", ShapeKind::Plane as u32 as f64),
    ];
    for (name, want) in cases {
        assert_eq!(constant(&m, name), want, "{name}");
    }
    let distance = parse("#import penumbra::df::distance\n");
    for (name, want) in [
        ("BRICK_TABLE_WIDTH", penumbra_df_core::bricks::TABLE_WIDTH),
        ("BRICK_EMPTY", penumbra_df_core::bricks::EMPTY),
        ("BRICK_SAMPLES", penumbra_df_core::bricks::BRICK_SAMPLES),
        (
            "BRICK_HEADER_ENTRIES",
            penumbra_df_core::bricks::HEADER_ENTRIES,
        ),
    ] {
        assert_eq!(constant(&distance, name), want as f64, "{name}");
    }
    assert_eq!(
        constant(&distance, "BRICK_COARSE_SLACK"),
        penumbra_sdf::bricks::COARSE_SLACK_VOXELS as f64
    );
    let deltas = parse("#import penumbra::df::apply_deltas\n");
    assert_eq!(
        constant(&deltas, "WRITE_WORDS") as usize,
        penumbra_df_core::table::DeltaWrite::WORDS
    );
}

#[test]
fn flatten_inlines_each_module_once_and_rejects_unknown_imports() {
    let text = flatten("#import penumbra::df::cull\n#import penumbra::df::object\n").unwrap();
    assert_eq!(text.matches("struct DistanceFieldObject").count(), 1);
    assert!(!text.contains("#import") && !text.contains("#define_import_path"));
    assert!(flatten("#import penumbra::nope\n").is_err());
    let item = flatten("#import penumbra::df::object::DistanceFieldObject\n").unwrap();
    assert!(item.contains("struct DistanceFieldObject"));
}

/// The shadow passes' uniforms have the sizes and member offsets their Rust encoders
/// (`penumbra_df_core::shadow`) write.
#[test]
fn shadow_uniform_layouts_match_the_encoders() {
    use penumbra_df_core::shadow::{SHADOW_LIGHT_BYTES, SHADOW_TRACE_VIEW_BYTES};
    let m = parse("#import penumbra::df::shadow_trace\n");
    let (members, size) = struct_layout(&m, "ShadowLight");
    assert_eq!(size as usize, SHADOW_LIGHT_BYTES);
    let got: Vec<(&str, u32)> = members.iter().map(|(n, o)| (n.as_str(), *o)).collect();
    // Word order of `ShadowLight::to_words`.
    let want = [
        ("position_or_direction", 0),
        ("source", 4),
        ("max_distance", 5),
        ("bias", 6),
        ("shaping", 7),
        ("range", 8),
        ("max_steps", 9),
        ("max_view_distance", 10),
        ("reserved", 11),
        ("spot", 12),
    ];
    let want: Vec<(&str, u32)> = want.iter().map(|&(n, w)| (n, w * 4)).collect();
    assert_eq!(got, want);

    let (members, size) = struct_layout(&m, "ShadowTraceView");
    assert_eq!(size as usize, SHADOW_TRACE_VIEW_BYTES);
    let got: Vec<(&str, u32)> = members.iter().map(|(n, o)| (n.as_str(), *o)).collect();
    // Word order of `trace_view_words`.
    let want = [
        ("view_from_clip", 0),
        ("world_from_view", 16),
        ("camera_tile", 28),
        ("camera_offset", 32),
        ("size", 36),
        ("viewport", 40),
    ];
    let want: Vec<(&str, u32)> = want.iter().map(|&(n, w)| (n, w * 4)).collect();
    assert_eq!(got, want);

    // The light cull reads the same view words as the frustum cull
    // (`penumbra_df_core::cull::cull_view_words`).
    let m = parse("#import penumbra::df::shadow_cull\n");
    let (shadow, shadow_size) = struct_layout(&m, "ShadowCullView");
    let m = parse("#import penumbra::df::cull\n");
    let (frustum, frustum_size) = struct_layout(&m, "CullView");
    assert_eq!(shadow_size, frustum_size);
    let offsets = |v: &[(String, u32)]| v.iter().map(|(_, o)| *o).collect::<Vec<_>>();
    assert_eq!(offsets(&shadow)[..5], offsets(&frustum)[..5]);
}

/// The light-space grid's uniform and storage layouts match `penumbra_df_core::shadow`.
#[test]
fn shadow_grid_layouts_match() {
    use penumbra_df_core::shadow::{
        SHADOW_GRID_BYTES, SHADOW_GRID_MAX_CELLS, SHADOW_GRID_VIEW_BYTES,
    };
    let m = parse("#import penumbra::df::shadow_grid\n");
    let (view, size) = struct_layout(&m, "ShadowGridView");
    assert_eq!(size as usize, SHADOW_GRID_VIEW_BYTES);
    let offsets: Vec<u32> = view.iter().map(|(_, o)| *o).collect();
    assert_eq!(offsets, [0, 16, 32, 48]);
    for name in ["ShadowGrid", "ShadowGridRead"] {
        let (members, size) = struct_layout(&m, name);
        assert_eq!(size as usize, SHADOW_GRID_BYTES, "{name}");
        let offsets: Vec<u32> = members.iter().map(|(_, o)| *o).collect();
        assert_eq!(offsets, [0, 16, 20, 24, 28, 32, 32 + 4096], "{name}");
    }
    assert_eq!(constant(&m, "MAX_CELLS") as usize, SHADOW_GRID_MAX_CELLS);
}

/// `AoTraceView` is laid out by `encase` from the Rust struct: the WGSL struct has the
/// same members in the same order and the same size; the cone constants match.
#[test]
fn ao_layouts_and_constants_match() {
    use encase::ShaderType;
    use penumbra_df_core::ao::{AoTraceView, GOLDEN_ANGLE, MAX_CONES, MIN_STEP_FRACTION};
    let m = parse("#import penumbra::df::ao\n");
    let (members, size) = struct_layout(&m, "AoTraceView");
    assert_eq!(u64::from(size), AoTraceView::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "view_from_clip",
            "world_from_view",
            "camera_tile",
            "slot_count",
            "camera_offset",
            "max_distance",
            "full_size",
            "trace_size",
            "jitter",
            "divisor",
            "cone_count",
            "steps_per_cone",
            "bias",
            "tan_half",
            "shaping",
            "influence",
            "tile_objects_debug",
            "far_distance",
            "heightfield_count",
            "origin",
        ]
    );
    assert_eq!(constant(&m, "MAX_CONES") as u32, MAX_CONES);
    assert_eq!(
        constant(&m, "TILE_OBJECTS_SCALE") as f32,
        penumbra_df_core::ao::TILE_OBJECTS_SCALE
    );
    assert_eq!(constant(&m, "GOLDEN_ANGLE") as f32, GOLDEN_ANGLE);
    assert_eq!(constant(&m, "MIN_STEP_FRACTION") as f32, MIN_STEP_FRACTION);
}

#[test]
fn ao_temporal_layout_and_constants_match() {
    use encase::ShaderType;
    use penumbra_df_core::ao::{
        AoTemporalView, CONFIDENCE_GAIN, FILL_CONFIDENCE, FILL_RADIUS, HISTORY_DEPTH_TOLERANCE,
        HISTORY_WEIGHT, LEAK_TOLERANCE,
    };
    let m = parse("#import penumbra::df::ao_temporal\n");
    let (members, size) = struct_layout(&m, "AoTemporalView");
    assert_eq!(u64::from(size), AoTemporalView::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "view_from_clip",
            "world_from_view",
            "previous_offset",
            "history_valid",
            "full_size",
            "confidence",
            "spatial_fill",
            "origin",
        ]
    );
    assert_eq!(constant(&m, "HISTORY_WEIGHT") as f32, HISTORY_WEIGHT);
    assert_eq!(
        constant(&m, "HISTORY_DEPTH_TOLERANCE") as f32,
        HISTORY_DEPTH_TOLERANCE
    );
    assert_eq!(constant(&m, "CONFIDENCE_GAIN") as f32, CONFIDENCE_GAIN);
    assert_eq!(constant(&m, "LEAK_TOLERANCE") as f32, LEAK_TOLERANCE);
    assert_eq!(constant(&m, "FILL_CONFIDENCE") as f32, FILL_CONFIDENCE);
    assert_eq!(constant(&m, "FILL_RADIUS") as i32, FILL_RADIUS);
    // The fill weighs neighbours as the upsample does (`dfao::UPSAMPLE_DEPTH_TOLERANCE`).
    assert_eq!(constant(&m, "UPSAMPLE_DEPTH_TOLERANCE") as f32, 0.1);
}

/// The global field's compose pass: `ComposeJob` and `ComposeParams` laid out by
/// `encase` as the WGSL structs, and the brick constants.
#[test]
fn global_compose_layouts_and_constants_match() {
    use encase::ShaderType;
    use penumbra_df_core::clipmap::{BRICK, ComposeJob, ComposeParams, MAX_LEVELS};
    let m = parse("#import penumbra::df::global_compose\n");
    let (members, size) = struct_layout(&m, "ComposeJob");
    assert_eq!(u64::from(size), ComposeJob::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["tile", "level", "first", "word"]);
    let (members, size) = struct_layout(&m, "ComposeParams");
    assert_eq!(u64::from(size), ComposeParams::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        ["levels", "slot_count", "job_count", "heightfield_count"]
    );
    assert_eq!(constant(&m, "BRICK") as u32, BRICK);
    assert_eq!(constant(&m, "MAX_LEVELS") as u32, MAX_LEVELS);
}

/// Heightfields: `HeightfieldRecord` laid out by `encase` as the WGSL struct (an array
/// element: its stride too), and the slope tile.
#[test]
fn heightfield_layout_and_constants_match() {
    use encase::ShaderType;
    use penumbra_df_core::heightfield::{HeightfieldRecord, SLOPE_TILE};
    let m = parse("#import penumbra::df::heightfield\n");
    let (members, size) = struct_layout(&m, "HeightfieldRecord");
    assert_eq!(u64::from(size), HeightfieldRecord::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        ["tile", "row", "origin", "extent", "size", "tiles", "bounds"]
    );
    let offsets: Vec<u32> = members.iter().map(|(_, o)| *o).collect();
    assert_eq!(offsets, [0, 12, 16, 24, 32, 40, 48]);
    assert_eq!(HeightfieldRecord::min_size().get(), 64);
    assert_eq!(constant(&m, "SLOPE_TILE") as u32, SLOPE_TILE);
}

/// The global field's sampler: `GlobalFieldView` (with its per-level structs) laid out
/// by `encase` as the WGSL structs, and the march's step constant.
#[test]
fn global_field_layouts_and_constants_match() {
    use encase::ShaderType;
    use penumbra_df_core::clipmap::{GlobalFieldLevel, GlobalFieldView};
    let m = parse("#import penumbra::df::global_field\n");
    let (members, size) = struct_layout(&m, "GlobalFieldLevel");
    assert_eq!(u64::from(size), GlobalFieldLevel::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "camera",
            "texel",
            "origin_mod",
            "band",
            "dilation",
            "quantum",
            "ready",
            "_pad"
        ]
    );
    let (members, size) = struct_layout(&m, "GlobalFieldView");
    assert_eq!(u64::from(size), GlobalFieldView::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "levels",
            "level_count",
            "resolution",
            "bricks_per_side",
            "valid_words"
        ]
    );
    assert_eq!(
        constant(&m, "FIELD_MIN_STEP_FRACTION") as f32,
        penumbra_df_core::ao::MIN_STEP_FRACTION
    );
}

/// Particles: `GpuParticle` and `ParticleStep` laid out by `encase` as the WGSL structs.
#[test]
fn particle_layouts_match() {
    use encase::ShaderType;
    use penumbra_df_core::particles::{GpuParticle, ParticleStep};
    let m = parse("#import penumbra::df::particles\n");
    let (members, size) = struct_layout(&m, "DistanceFieldParticle");
    assert_eq!(u64::from(size), GpuParticle::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["position", "age", "velocity", "alive"]);
    let (members, size) = struct_layout(&m, "ParticleStep");
    assert_eq!(u64::from(size), ParticleStep::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "gravity",
            "dt",
            "origin",
            "restitution",
            "friction",
            "radius",
            "count"
        ]
    );
}

/// The posed-mesh re-bake: `RebakeParams` laid out by `encase` as the WGSL struct, and
/// the tile and workgroup the Rust side dispatches by.
#[test]
fn rebake_layout_and_constants_match() {
    use encase::ShaderType;
    use penumbra_df_core::rebake::{RebakeParams, TRIANGLE_TILE, WORKGROUP_SAMPLES};
    let m = parse("#import penumbra::df::rebake\n");
    let (members, size) = struct_layout(&m, "RebakeParams");
    assert_eq!(u64::from(size), RebakeParams::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        ["voxel_size", "resolution", "triangles", "row_words"]
    );
    assert_eq!(constant(&m, "TRIANGLE_TILE") as u32, TRIANGLE_TILE);
    let entry = m
        .entry_points
        .iter()
        .find(|e| e.name == "rebake")
        .expect("entry point");
    // Two samples along x per invocation.
    assert_eq!(
        [
            2 * entry.workgroup_size[0],
            entry.workgroup_size[1],
            entry.workgroup_size[2]
        ],
        WORKGROUP_SAMPLES.to_array()
    );
    assert_eq!(entry.workgroup_size.iter().product::<u32>(), TRIANGLE_TILE);
}

#[test]
fn bokeh_layouts_and_constants_match() {
    use encase::ShaderType;
    use penumbra_cinematic_core::dof::{
        BokehView, HALF_RES_BLUR, NORM_INTERVALS, NORM_TABLE_MAX, NORM_TABLE_STEPS,
        QUARTER_RES_BLUR,
    };
    let m = parse("#import penumbra::dof::types\n");
    let (members, size) = struct_layout(&m, "BokehView");
    assert_eq!(u64::from(size), BokehView::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "view_from_clip",
            "full_size",
            "half_size",
            "quarter_size",
            "coc_scale",
            "focal_distance",
            "max_coc",
            "max_depth",
            "min_coc",
            "coc_tolerance",
            "color_tolerance",
            "depth_tolerance",
            "merge",
            "merge_groups",
            "capacity",
            "quarter_diameter",
            "origin",
        ]
    );
    let (_, sprite) = struct_layout(&m, "Sprite");
    assert_eq!(sprite, 32);
    assert_eq!(constant(&m, "HALF_RES_BLUR") as f32, HALF_RES_BLUR);
    assert_eq!(constant(&m, "QUARTER_RES_BLUR") as f32, QUARTER_RES_BLUR);
    let compact = parse("#import penumbra::dof::compact\n");
    let (_, args) = struct_layout(&compact, "DrawArgs");
    assert_eq!(args, 16);
    // Four draws' arguments, then the layers' first indices (the plugin's
    // `LAYER_DRAWS_BYTES`).
    let (_, draws) = struct_layout(&compact, "LayerDraws");
    assert_eq!(draws, 80);
    let scatter = parse("#import penumbra::dof::scatter\n");
    assert_eq!(constant(&scatter, "NORM_TABLE_MAX") as f32, NORM_TABLE_MAX);
    assert_eq!(
        constant(&scatter, "NORM_TABLE_STEPS") as f32,
        NORM_TABLE_STEPS as f32
    );
    assert_eq!(
        constant(&scatter, "NORM_INTERVALS") as usize,
        NORM_INTERVALS
    );
}

/// Billboard reflections: `ReflectionUniform` and `GpuBillboard` laid out by `encase` as
/// the WGSL structs (the same members in the same order, the same size).
#[test]
fn reflection_layouts_match() {
    use encase::ShaderType;
    use penumbra_cinematic_core::reflections::pass::{GpuBillboard, ReflectionUniform};
    let m = parse("#import penumbra::reflections::types\n");
    let (members, size) = struct_layout(&m, "ReflectionUniform");
    assert_eq!(u64::from(size), ReflectionUniform::min_size().get());
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "billboard_count",
            "max_layers",
            "max_distance",
            "anisotropy",
            "texture_size",
            "mip_count",
            "half_resolution",
            "camera_tile",
            "object_count",
            "camera_offset",
            "footprint_slope",
            "shadow_steps",
            "shadow_bias",
            "shadow_softness",
            "taps",
            "tiles_x",
            "tile_capacity",
            "trace_size",
            "shadow_cone",
            "caster_capacity",
            "view_layers",
            "caster_grid",
        ]
    );
    let (_, billboard) = struct_layout(&m, "GpuBillboard");
    assert_eq!(u64::from(billboard), GpuBillboard::min_size().get());
    // The caster grid's layout in the view's list buffer (`grid::grid_words`).
    use penumbra_cinematic_core::reflections::grid;
    assert_eq!(constant(&m, "GRID_DIM") as u32, grid::GRID_DIM);
    assert_eq!(constant(&m, "GRID_CELLS") as u32, grid::GRID_CELLS);
    assert_eq!(constant(&m, "GRID_HEADER") as u32, grid::GRID_HEADER_WORDS);
    assert_eq!(
        constant(&m, "GRID_OVER_LIST") as usize,
        grid::GRID_OVER_LIST
    );
}
