//! Render-world side of Penumbra's lighting pass.

use super::msaa::DeferredMsaaShading;
use super::msaa_render::{self, DeferredMsaaTextures, LightingVariant, MSAA_VARIANTS};
use super::{PenumbraLightingView, PenumbraSpecularLayer};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::core_3d::main_opaque_pass_3d;
use bevy::core_pipeline::deferred::{
    DEFERRED_LIGHTING_PASS_ID_DEPTH_FORMAT, copy_lighting_id::DeferredLightingIdDepthTexture,
};
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::pbr::{
    MeshPipeline, MeshPipelineKey, MeshPipelineSystems, MeshViewBindGroup,
    TONEMAPPING_LUT_SAMPLER_BINDING_INDEX, TONEMAPPING_LUT_TEXTURE_BINDING_INDEX, ViewKeyCache,
    per_view_shadow_pass, screen_space_reflections, shared_shadow_pass,
};
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_2d, texture_2d_array, texture_2d_multisampled,
    uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferUsages, CachedRenderPipelineId, ColorTargetState, ColorWrites, CompareFunction,
    DepthStencilState, Extent3d, FragmentState, LoadOp, Operations, PipelineCache,
    RenderPassColorAttachment, RenderPassDepthStencilAttachment, RenderPassDescriptor,
    RenderPipelineDescriptor, ShaderStages, ShaderType, SpecializedRenderPipeline,
    SpecializedRenderPipelines, StoreOp, TextureDescriptor, TextureDimension, TextureFormat,
    TextureSampleType, TextureUsages, TextureView, TextureViewDescriptor, TextureViewDimension,
    TextureViewId, VertexState,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Render, RenderStartup, RenderSystems};
use bevy::shader::ShaderDefVal;
use std::num::NonZeroU64;

/// Bevy's (crate-private) `IRRADIANCE_VOLUMES_ARE_USABLE`: off on the web, where they
/// overflow the texture bindings of deferred rendering.
const IRRADIANCE_VOLUMES_ARE_USABLE: bool = cfg!(not(target_arch = "wasm32"));
/// Penumbra's systems in `Core3d`'s main pass, in order (each set runs after the one
/// before it; the whole chain after Bevy's deferred lighting, and before Bevy's
/// screen-space reflections, which reflect the lit image, and the opaque pass).
#[derive(bevy::ecs::schedule::SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PenumbraLightingSystems {
    /// Passes that make the lighting pass's inputs: distance-field shadow masks, AO.
    Inputs,
    /// Passes that make the view's specular layer (`PenumbraSpecularLayer`), which the
    /// shading draws and the lighting pass read: billboard reflections.
    Specular,
    /// Other draws shading G-buffer samples from those inputs, before the lighting pass
    /// (which discards the lighting-id depth they test against): subsurface scattering.
    Shading,
    /// Penumbra's lighting pass.
    Lighting,
}

/// Bytes of one `PenumbraShadowedLight` (`lighting/masks.wgsl`).
const SHADOWED_LIGHT_BYTES: u64 = 32;

/// Which light a mask belongs to.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    not(feature = "shadows"),
    allow(dead_code, reason = "only distance-field shadows make masks so far")
)]
pub enum ShadowedLightKind {
    /// A directional light, identified by its unit direction toward the light (Bevy
    /// exposes no index for directional lights: the shader matches directions).
    Directional {
        /// Unit vector toward the light.
        direction: Vec3,
    },
    /// A point or spot light, by its clustered light id
    /// (`GlobalClusterableObjectMeta::entity_to_index`).
    Clustered {
        /// Index into Bevy's clustered light array.
        light_id: u32,
    },
}

/// One light whose visibility the lighting pass reads from a mask layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PenumbraShadowedLight {
    /// The light.
    pub kind: ShadowedLightKind,
    /// Layer of [`PenumbraLightingInputs::masks`] holding its visibility (1 lit, 0
    /// shadowed), one texel per view pixel.
    pub layer: u32,
    /// The light's main-world entity (names the layer in buffer dumps).
    pub light: bevy::render::sync_world::MainEntity,
}

/// A view's shadow masks, inserted on the render-world view by the features that make
/// them (distance-field shadows). Without it every light uses Bevy's shadow maps.
#[derive(Component, Clone)]
pub struct PenumbraLightingInputs {
    /// The lights with a mask.
    pub lights: Vec<PenumbraShadowedLight>,
    /// `texture_2d_array<f32>` at the view's size, one layer per masked light.
    pub masks: TextureView,
    /// Deferred MSAA: the masks of the pixels shaded per sample, per sample
    /// (`texture_2d_array<f32>` at twice the view's size, each pixel's samples in a 2×2
    /// block); `None`: those samples read `masks`.
    pub sample_masks: Option<TextureView>,
}

/// A view's distance-field AO, inserted on the render-world view by the DFAO feature:
/// the lighting pass occludes indirect light with it. Without it the AO is 1.
#[derive(Component, Clone)]
pub struct PenumbraAoInput {
    /// `Rgba16Float` at the view's size: AO, then the world-space bent normal.
    pub texture: TextureView,
    /// Deferred MSAA: the AO of the pixels shaded per sample, per sample (`Rgba16Float`
    /// at twice the view's size, laid out as the per-sample shadow masks); `None`:
    /// those samples read `texture`.
    pub samples: Option<TextureView>,
    /// Contrast, `[0, 1]`.
    pub contrast: f32,
    /// Min occlusion, `[0, 1]`.
    pub min_occlusion: f32,
    /// Occlusion tint (linear, `AmbientLight` units).
    pub tint: LinearRgba,
    /// 0 none, 1 non-directional, 2 cone–cone.
    pub specular_occlusion: u32,
    /// 0 shading, 1 AO, 2 bent normal.
    pub debug_view: u32,
}

/// Deferred lighting pass ids that Penumbra's lighting pass also shades, as ordinary
/// `StandardMaterial`s, on `DeferredMsaa` views: `from..=255` (256: none, the default).
/// Subsurface scattering's profiles register theirs (`192..`): without it those
/// materials went unlit on deferred MSAA cameras, where no other pass draws them.
/// Render world.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq)]
pub struct MsaaShadedLightingIds {
    /// The first such id.
    pub from: u32,
}

impl Default for MsaaShadedLightingIds {
    fn default() -> Self {
        Self { from: 256 }
    }
}

/// `PenumbraLightingUniform` (`lighting/masks.wgsl`).
#[derive(ShaderType, Clone, Copy, Default)]
struct PenumbraLightingUniform {
    depth_id: u32,
    shadowed_light_count: u32,
    ao_enabled: u32,
    ao_specular_occlusion: u32,
    ao_tint: Vec4,
    ao_contrast: f32,
    ao_min_occlusion: f32,
    ao_debug_view: u32,
    /// `PenumbraSpecularLayer`: 0 none, 1 full resolution, 2 half; +4 debug view.
    specular_layer: u32,
    /// [`MsaaShadedLightingIds::from`].
    msaa_shaded_ids_from: u32,
}

/// `PenumbraMsaaUniform` (`lighting/msaa_view.wgsl`).
#[derive(ShaderType, Clone, Copy)]
struct PenumbraMsaaUniform {
    edge: penumbra_df_core::msaa::EdgeParams,
    per_sample_everywhere: u32,
    show_edges: u32,
    sample_shadows: u32,
    sample_ao: u32,
}

/// The lighting pass's pipeline family and its group 2.
#[derive(Resource)]
pub struct PenumbraLightingPipeline {
    mesh_pipeline: MeshPipeline,
    layout: BindGroupLayoutDescriptor,
    /// Group 2 of deferred MSAA's draws: `layout`'s entries, then the MSAA uniform, the
    /// multisampled G-buffer and lighting id, the pixels' classes, and the per-sample
    /// masks and AO.
    msaa_layout: BindGroupLayoutDescriptor,
    shader: Handle<Shader>,
    classify_shader: Handle<Shader>,
    /// One white layer: bound when a view has no masks.
    pub(crate) no_masks: TextureView,
    /// One texel: bound when a view has no AO.
    pub(crate) no_ao: TextureView,
    /// One `R8Uint` texel: the classes' slot while the classification writes them.
    no_class: TextureView,
}

/// A view's specialised lighting pipelines.
#[derive(Component)]
pub struct PenumbraLightingPipelineId {
    /// Without MSAA: the one draw.
    pub single: Option<CachedRenderPipelineId>,
    /// Deferred MSAA: classification, the two stencil marks, per pixel, per sample.
    pub msaa: Option<[CachedRenderPipelineId; 5]>,
}

/// A view's group 2 and the buffers behind it (reused across frames; the bind groups
/// are made again only when the textures they bind change).
#[derive(Component)]
pub struct PenumbraLightingBindGroup {
    uniform: Buffer,
    lights: Buffer,
    light_capacity: u64,
    msaa_uniform: Option<Buffer>,
    bind_group: Option<(BindGroup, Vec<TextureViewId>)>,
    /// Deferred MSAA's classification group (the classes' slot holds a placeholder).
    classify_bind_group: Option<BindGroup>,
}

impl PenumbraLightingBindGroup {
    /// The single-sample lighting draw's group 2 (shadow masks, AO), once made.
    pub fn bind_group(&self) -> Option<&BindGroup> {
        self.bind_group.as_ref().map(|(group, _)| group)
    }

    pub(crate) fn classify_bind_group(&self) -> Option<&BindGroup> {
        self.classify_bind_group.as_ref()
    }
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<SpecializedRenderPipelines<PenumbraLightingPipeline>>()
        .init_resource::<MsaaShadedLightingIds>()
        .add_systems(
            Render,
            (
                timed(prepare_penumbra_lighting_pipelines).in_set(RenderSystems::Prepare),
                timed(prepare_penumbra_lighting_bind_groups)
                    .in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Render,
            timed(msaa_render::prepare_deferred_msaa_textures)
                .in_set(RenderSystems::PrepareResourcesFlush),
        )
        .configure_sets(
            Core3d,
            (
                PenumbraLightingSystems::Inputs,
                PenumbraLightingSystems::Specular,
                PenumbraLightingSystems::Shading.after(bevy::pbr::deferred::deferred_lighting),
                PenumbraLightingSystems::Lighting
                    .before(screen_space_reflections)
                    .before(main_opaque_pass_3d),
            )
                .chain()
                .in_set(Core3dSystems::MainPass),
        )
        .add_systems(
            Core3d,
            (
                timed(penumbra_lighting).in_set(PenumbraLightingSystems::Lighting),
                // The prepass textures are swapped while Bevy's shadow passes (which
                // read them) wait: before the early ones, after the late ones.
                timed(msaa_render::swap_in_msaa_gbuffer)
                    .before(Core3dSystems::Prepass)
                    .before(per_view_shadow_pass::<false>)
                    .before(shared_shadow_pass::<false>),
                (
                    timed(msaa_render::swap_out_msaa_gbuffer),
                    timed(msaa_render::classify_deferred_msaa),
                )
                    .chain()
                    .after(Core3dSystems::Prepass)
                    .after(per_view_shadow_pass::<true>)
                    .after(shared_shadow_pass::<true>)
                    .before(Core3dSystems::MainPass),
            ),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(
        RenderStartup,
        init_penumbra_lighting_pipeline.after(MeshPipelineSystems),
    );
}

fn init_penumbra_lighting_pipeline(
    mut commands: Commands,
    mesh_pipeline: Res<MeshPipeline>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return;
    };
    let common = (
        uniform_buffer_sized(false, Some(PenumbraLightingUniform::min_size())),
        storage_buffer_read_only_sized(false, NonZeroU64::new(SHADOWED_LIGHT_BYTES)),
        texture_2d_array(TextureSampleType::Float { filterable: false }),
        texture_2d(TextureSampleType::Float { filterable: false }),
    );
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_lighting_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::VERTEX_FRAGMENT,
            (common.0, common.1, common.2, common.3, common.3),
        ),
    );
    let msaa_layout = BindGroupLayoutDescriptor::new(
        "penumbra_lighting_msaa_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::VERTEX_FRAGMENT,
            (
                common.0,
                common.1,
                common.2,
                common.3,
                uniform_buffer_sized(false, Some(PenumbraMsaaUniform::min_size())),
                texture_2d_multisampled(TextureSampleType::Uint),
                texture_2d_multisampled(TextureSampleType::Uint),
                texture_2d(TextureSampleType::Uint),
                common.2,
                common.3,
                common.3,
            ),
        ),
    );
    let one_texel = |label, format| {
        device.create_texture(&TextureDescriptor {
            label: Some(label),
            size: Extent3d {
                width: 1,
                height: 1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D2,
            format,
            usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
            view_formats: &[],
        })
    };
    let texture = one_texel("penumbra_lighting_no_masks", TextureFormat::R32Float);
    queue.write_texture(
        texture.as_image_copy(),
        &1.0f32.to_le_bytes(),
        bevy::render::render_resource::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(4),
            rows_per_image: None,
        },
        Extent3d {
            width: 1,
            height: 1,
            depth_or_array_layers: 1,
        },
    );
    let no_masks = texture.create_view(&TextureViewDescriptor {
        dimension: Some(TextureViewDimension::D2Array),
        ..default()
    });
    let no_ao = texture.create_view(&TextureViewDescriptor {
        dimension: Some(TextureViewDimension::D2),
        ..default()
    });
    let no_class = one_texel("penumbra_lighting_no_class", TextureFormat::R8Uint)
        .create_view(&TextureViewDescriptor::default());
    commands.insert_resource(PenumbraLightingPipeline {
        mesh_pipeline: mesh_pipeline.clone(),
        layout,
        msaa_layout,
        shader: library.handle("lighting/pass.wgsl"),
        classify_shader: library.handle("lighting/msaa_classify.wgsl"),
        no_masks,
        no_ao,
        no_class,
    });
}

impl PenumbraLightingPipeline {
    /// The single-sample lighting pipeline of a view (`key`: the view's
    /// `MeshPipelineKey`, from Bevy's `ViewKeyCache`): Bevy's view bind groups 0 and 1,
    /// Penumbra's group 2 ([`Self::layout`]), `lighting/pass.wgsl`'s `fragment` into the
    /// view's target, depth-tested for equality against Bevy's lighting-id texture.
    /// Passes that shade G-buffer samples another way (subsurface scattering's split
    /// lighting) start from it and change the entry point, targets or depth test.
    pub fn view_descriptor(&self, key: MeshPipelineKey) -> RenderPipelineDescriptor {
        self.specialize((key, LightingVariant::Single))
    }

    /// The deferred MSAA counterpart of [`Self::view_descriptor`], for passes that shade
    /// a `DeferredMsaa` view's pixels another way (subsurface scattering): Bevy's
    /// multisampled view layouts, Penumbra's MSAA group 2 (the multisampled G-buffer and
    /// lighting ids, `lighting/msaa_view.wgsl`), `PENUMBRA_MSAA` and `MULTISAMPLED`
    /// defined; single-sample, no depth or stencil test. Callers set the entry point,
    /// targets and sample count.
    pub fn msaa_view_descriptor(&self, key: MeshPipelineKey) -> RenderPipelineDescriptor {
        let mut desc = self.specialize((key, LightingVariant::PerPixel));
        desc.depth_stencil = None;
        desc.multisample = default();
        desc
    }

    /// Group 2 of single-sample lighting draws.
    pub fn layout(&self) -> &BindGroupLayoutDescriptor {
        &self.layout
    }

    /// `lighting/pass.wgsl`.
    pub fn shader(&self) -> &Handle<Shader> {
        &self.shader
    }
}

impl SpecializedRenderPipeline for PenumbraLightingPipeline {
    type Key = (MeshPipelineKey, LightingVariant);

    /// The shader definitions follow Bevy's deferred lighting pipeline: the view bind
    /// group layout (chosen from the same key) must match what the shader declares.
    fn specialize(&self, (key, variant): Self::Key) -> RenderPipelineDescriptor {
        let mut defs: Vec<ShaderDefVal> = vec![
            "DEFERRED_LIGHTING_PIPELINE".into(),
            "DEFERRED_PREPASS".into(),
            "STANDARD_MATERIAL_CLEARCOAT".into(),
        ];
        if key.contains(MeshPipelineKey::TONEMAP_IN_SHADER) {
            defs.push("TONEMAP_IN_SHADER".into());
            defs.push(ShaderDefVal::UInt(
                "TONEMAPPING_LUT_TEXTURE_BINDING_INDEX".into(),
                TONEMAPPING_LUT_TEXTURE_BINDING_INDEX,
            ));
            defs.push(ShaderDefVal::UInt(
                "TONEMAPPING_LUT_SAMPLER_BINDING_INDEX".into(),
                TONEMAPPING_LUT_SAMPLER_BINDING_INDEX,
            ));
            let method = key.intersection(MeshPipelineKey::TONEMAP_METHOD_RESERVED_BITS);
            let name = [
                (MeshPipelineKey::TONEMAP_METHOD_NONE, "TONEMAP_METHOD_NONE"),
                (
                    MeshPipelineKey::TONEMAP_METHOD_REINHARD,
                    "TONEMAP_METHOD_REINHARD",
                ),
                (
                    MeshPipelineKey::TONEMAP_METHOD_REINHARD_LUMINANCE,
                    "TONEMAP_METHOD_REINHARD_LUMINANCE",
                ),
                (
                    MeshPipelineKey::TONEMAP_METHOD_ACES_FITTED,
                    "TONEMAP_METHOD_ACES_FITTED",
                ),
                (MeshPipelineKey::TONEMAP_METHOD_AGX, "TONEMAP_METHOD_AGX"),
                (
                    MeshPipelineKey::TONEMAP_METHOD_SOMEWHAT_BORING_DISPLAY_TRANSFORM,
                    "TONEMAP_METHOD_SOMEWHAT_BORING_DISPLAY_TRANSFORM",
                ),
                (
                    MeshPipelineKey::TONEMAP_METHOD_BLENDER_FILMIC,
                    "TONEMAP_METHOD_BLENDER_FILMIC",
                ),
                (
                    MeshPipelineKey::TONEMAP_METHOD_TONY_MC_MAPFACE,
                    "TONEMAP_METHOD_TONY_MC_MAPFACE",
                ),
                (
                    MeshPipelineKey::TONEMAP_METHOD_PBR_NEUTRAL,
                    "TONEMAP_METHOD_PBR_NEUTRAL",
                ),
            ]
            .into_iter()
            .find(|(bits, _)| method == *bits)
            .map(|(_, name)| name);
            if let Some(name) = name {
                defs.push(name.into());
            }
            if key.contains(MeshPipelineKey::DEBAND_DITHER) {
                defs.push("DEBAND_DITHER".into());
            }
        }
        for (flag, def) in [
            (
                MeshPipelineKey::SCREEN_SPACE_AMBIENT_OCCLUSION,
                "SCREEN_SPACE_AMBIENT_OCCLUSION",
            ),
            (MeshPipelineKey::ENVIRONMENT_MAP, "ENVIRONMENT_MAP"),
            (MeshPipelineKey::NORMAL_PREPASS, "NORMAL_PREPASS"),
            (MeshPipelineKey::DEPTH_PREPASS, "DEPTH_PREPASS"),
            (
                MeshPipelineKey::MOTION_VECTOR_PREPASS,
                "MOTION_VECTOR_PREPASS",
            ),
            (
                MeshPipelineKey::SCREEN_SPACE_REFLECTIONS,
                "SCREEN_SPACE_REFLECTIONS",
            ),
            (MeshPipelineKey::CONTACT_SHADOWS, "CONTACT_SHADOWS"),
            (MeshPipelineKey::HAS_PREVIOUS_SKIN, "HAS_PREVIOUS_SKIN"),
            (MeshPipelineKey::HAS_PREVIOUS_MORPH, "HAS_PREVIOUS_MORPH"),
            (MeshPipelineKey::DISTANCE_FOG, "DISTANCE_FOG"),
            (MeshPipelineKey::ATMOSPHERE, "ATMOSPHERE"),
        ] {
            if key.contains(flag) {
                defs.push(def.into());
            }
        }
        if key.contains(MeshPipelineKey::IRRADIANCE_VOLUME) && IRRADIANCE_VOLUMES_ARE_USABLE {
            defs.push("IRRADIANCE_VOLUME".into());
        }
        let filter = key.intersection(MeshPipelineKey::SHADOW_FILTER_METHOD_RESERVED_BITS);
        if filter == MeshPipelineKey::SHADOW_FILTER_METHOD_HARDWARE_2X2 {
            defs.push("SHADOW_FILTER_METHOD_HARDWARE_2X2".into());
        } else if filter == MeshPipelineKey::SHADOW_FILTER_METHOD_GAUSSIAN {
            defs.push("SHADOW_FILTER_METHOD_GAUSSIAN".into());
        } else if filter == MeshPipelineKey::SHADOW_FILTER_METHOD_TEMPORAL {
            defs.push("SHADOW_FILTER_METHOD_TEMPORAL".into());
        }
        if self.mesh_pipeline.binding_arrays_are_usable {
            defs.push("MULTIPLE_LIGHT_PROBES_IN_ARRAY".into());
            defs.push("MULTIPLE_LIGHTMAPS_IN_ARRAY".into());
        }
        if IRRADIANCE_VOLUMES_ARE_USABLE {
            defs.push("IRRADIANCE_VOLUMES_ARE_USABLE".into());
        }
        if self.mesh_pipeline.clustered_decals_are_usable {
            defs.push("CLUSTERED_DECALS_ARE_USABLE".into());
        }
        let msaa = variant != LightingVariant::Single;
        if msaa {
            defs.push("PENUMBRA_MSAA".into());
            defs.push("MULTISAMPLED".into());
        }
        let view_layout = self.mesh_pipeline.get_view_layout(key.into());
        let mut desc = RenderPipelineDescriptor {
            label: Some("penumbra_lighting_pipeline".into()),
            layout: vec![
                view_layout.main_layout,
                view_layout.binding_array_layout,
                if msaa {
                    self.msaa_layout.clone()
                } else {
                    self.layout.clone()
                },
            ],
            vertex: VertexState {
                shader: self.shader.clone(),
                shader_defs: defs.clone(),
                ..default()
            },
            fragment: Some(FragmentState {
                shader: self.shader.clone(),
                shader_defs: defs,
                targets: vec![Some(ColorTargetState {
                    format: key.target_format(),
                    blend: None,
                    write_mask: ColorWrites::ALL,
                })],
                ..default()
            }),
            depth_stencil: Some(DepthStencilState {
                format: DEFERRED_LIGHTING_PASS_ID_DEPTH_FORMAT,
                depth_write_enabled: Some(false),
                depth_compare: Some(CompareFunction::Equal),
                stencil: default(),
                bias: default(),
            }),
            ..default()
        };
        msaa_render::specialize_variant(&mut desc, variant, &self.classify_shader);
        desc
    }
}

fn prepare_penumbra_lighting_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    view_key_cache: Res<ViewKeyCache>,
    mut pipelines: ResMut<SpecializedRenderPipelines<PenumbraLightingPipeline>>,
    pipeline: Option<Res<PenumbraLightingPipeline>>,
    views: Query<(Entity, &ExtractedView, &PenumbraLightingView)>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    for (entity, view, lighting) in &views {
        // The same key as Bevy's forward and deferred passes for this view.
        let Some(key) = view_key_cache.get(&view.retained_view_entity) else {
            continue;
        };
        let mut specialize =
            |variant| pipelines.specialize(&pipeline_cache, &pipeline, (*key, variant));
        let ids = if lighting.msaa.is_some() {
            PenumbraLightingPipelineId {
                single: None,
                msaa: Some(MSAA_VARIANTS.map(&mut specialize)),
            }
        } else {
            PenumbraLightingPipelineId {
                single: Some(specialize(LightingVariant::Single)),
                msaa: None,
            }
        };
        commands.entity(entity).insert(ids);
    }
}

#[allow(
    clippy::type_complexity,
    clippy::too_many_arguments,
    reason = "a Bevy system"
)]
fn prepare_penumbra_lighting_bind_groups(
    mut commands: Commands,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipeline_cache: Res<PipelineCache>,
    pipeline: Option<Res<PenumbraLightingPipeline>>,
    shaded_ids: Res<MsaaShadedLightingIds>,
    mut views: Query<(
        Entity,
        &PenumbraLightingView,
        Option<&PenumbraLightingInputs>,
        Option<&PenumbraAoInput>,
        Option<&PenumbraSpecularLayer>,
        Option<&DeferredMsaaTextures>,
        Option<&mut PenumbraLightingBindGroup>,
    )>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    for (entity, view, inputs, ao, layer, msaa_textures, bind_group) in &mut views {
        let msaa = view.msaa.as_ref().zip(msaa_textures);
        let lights = inputs.map_or(&[][..], |i| i.lights.as_slice());
        let needed = (lights.len() as u64).max(1);
        let mut fresh = None;
        let group = match bind_group {
            Some(group) if group.light_capacity >= needed => group.into_inner(),
            _ => {
                let capacity = needed.next_power_of_two();
                fresh = Some(PenumbraLightingBindGroup {
                    uniform: allocations.sized_buffer(
                        &device,
                        "penumbra_lighting_uniform",
                        PenumbraLightingUniform::min_size().get(),
                        BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                    ),
                    lights: allocations.sized_buffer(
                        &device,
                        "penumbra_lighting_shadowed_lights",
                        capacity * SHADOWED_LIGHT_BYTES,
                        BufferUsages::STORAGE | BufferUsages::COPY_DST,
                    ),
                    light_capacity: capacity,
                    msaa_uniform: None,
                    bind_group: None,
                    classify_bind_group: None,
                });
                fresh.as_mut().expect("just set")
            }
        };
        let uniform = PenumbraLightingUniform {
            depth_id: view.depth_id,
            shadowed_light_count: lights.len() as u32,
            ao_enabled: u32::from(ao.is_some()),
            ao_specular_occlusion: ao.map_or(0, |a| a.specular_occlusion),
            ao_tint: ao.map_or(Vec4::ZERO, |a| a.tint.to_vec4()),
            ao_contrast: ao.map_or(0.0, |a| a.contrast),
            ao_min_occlusion: ao.map_or(0.0, |a| a.min_occlusion),
            ao_debug_view: ao.map_or(0, |a| a.debug_view),
            specular_layer: layer.map_or(0, PenumbraSpecularLayer::mode),
            msaa_shaded_ids_from: if msaa.is_some() { shaded_ids.from } else { 256 },
        };
        let mut bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
        bytes.write(&uniform).expect("fixed-size uniform");
        queue.write_buffer(&group.uniform, 0, bytes.as_ref());
        if !lights.is_empty() {
            queue.write_buffer(&group.lights, 0, &encode_shadowed_lights(lights));
        }
        let masks = inputs.map_or(&pipeline.no_masks, |i| &i.masks);
        let ao_texture = ao.map_or(&pipeline.no_ao, |a| &a.texture);
        let layer_texture = layer.map_or(&pipeline.no_ao, |l| &l.texture);
        let mut key = vec![masks.id(), ao_texture.id(), layer_texture.id()];
        let sample_masks = inputs.and_then(|i| i.sample_masks.as_ref());
        let sample_ao = ao.and_then(|a| a.samples.as_ref());
        let Some((settings, textures)) = msaa else {
            if group.bind_group.as_ref().map(|(_, id)| id) != Some(&key) {
                let bind_group = allocations.bind_group(
                    &device,
                    "penumbra_lighting_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipeline.layout),
                    &BindGroupEntries::sequential((
                        group.uniform.as_entire_binding(),
                        group.lights.as_entire_binding(),
                        masks,
                        ao_texture,
                        layer_texture,
                    )),
                );
                group.bind_group = Some((bind_group, key));
                group.classify_bind_group = None;
            }
            if let Some(fresh) = fresh {
                commands.entity(entity).insert(fresh);
            }
            continue;
        };
        let msaa_uniform = group
            .msaa_uniform
            .get_or_insert_with(|| {
                allocations.sized_buffer(
                    &device,
                    "penumbra_lighting_msaa_uniform",
                    PenumbraMsaaUniform::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                )
            })
            .clone();
        let uniform = PenumbraMsaaUniform {
            edge: settings.edge_params(),
            per_sample_everywhere: u32::from(settings.shading == DeferredMsaaShading::EverySample),
            show_edges: u32::from(settings.show_edges),
            sample_shadows: u32::from(sample_masks.is_some()),
            sample_ao: u32::from(sample_ao.is_some()),
        };
        let mut bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
        bytes.write(&uniform).expect("fixed-size uniform");
        queue.write_buffer(&msaa_uniform, 0, bytes.as_ref());
        let sample_masks = sample_masks.unwrap_or(&pipeline.no_masks);
        let sample_ao = sample_ao.unwrap_or(&pipeline.no_ao);
        key.extend([
            textures.gbuffer_view.id(),
            textures.lighting_id_view.id(),
            textures.class.default_view.id(),
            sample_masks.id(),
            sample_ao.id(),
        ]);
        if group.bind_group.as_ref().map(|(_, id)| id) != Some(&key) {
            let layout = pipeline_cache.get_bind_group_layout(&pipeline.msaa_layout);
            let make = |label, class| {
                allocations.bind_group(
                    &device,
                    label,
                    &layout,
                    &BindGroupEntries::sequential((
                        group.uniform.as_entire_binding(),
                        group.lights.as_entire_binding(),
                        masks,
                        ao_texture,
                        msaa_uniform.as_entire_binding(),
                        &textures.gbuffer_view,
                        &textures.lighting_id_view,
                        class,
                        sample_masks,
                        sample_ao,
                        layer_texture,
                    )),
                )
            };
            let lighting = make(
                "penumbra_lighting_msaa_bind_group",
                &textures.class.default_view,
            );
            group.classify_bind_group = Some(make(
                "penumbra_msaa_classify_bind_group",
                &pipeline.no_class,
            ));
            group.bind_group = Some((lighting, key));
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// `PenumbraShadowedLight` records as `lighting/masks.wgsl` reads them.
pub(crate) fn encode_shadowed_lights(lights: &[PenumbraShadowedLight]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(lights.len() * SHADOWED_LIGHT_BYTES as usize);
    for light in lights {
        let (kind, id, direction) = match light.kind {
            ShadowedLightKind::Directional { direction } => (0u32, 0u32, direction),
            ShadowedLightKind::Clustered { light_id } => (1, light_id, Vec3::ZERO),
        };
        for w in [kind, id, light.layer, 0] {
            bytes.extend_from_slice(&w.to_le_bytes());
        }
        for f in [direction.x, direction.y, direction.z, 0.0] {
            bytes.extend_from_slice(&f.to_le_bytes());
        }
    }
    bytes
}

/// The view's main colour target as the passes of Bevy's main pass before its opaque
/// pass draw into it: on an MSAA view the samples only, stored, not resolved — Bevy's
/// main opaque pass, which every 3D view runs after them, resolves them (a resolve per
/// pass wrote the whole single-sample texture again each time); on other views the
/// target itself.
pub fn unresolved_color_attachment(target: &ViewTarget) -> RenderPassColorAttachment<'_> {
    RenderPassColorAttachment {
        resolve_target: None,
        ..target.get_color_attachment()
    }
}

/// Binds the lighting pass's groups: Bevy's view (0, 1) and Penumbra's (2).
pub fn set_lighting_bind_groups<'a>(
    pass: &mut bevy::render::render_phase::TrackedRenderPass<'a>,
    mesh_view: &'a MeshViewBindGroup,
    group: &'a BindGroup,
) {
    pass.set_bind_group(0, &mesh_view.main, &mesh_view.main_offsets);
    pass.set_bind_group(1, &mesh_view.binding_array, &[]);
    pass.set_bind_group(2, group, &[]);
}

/// The lighting pass: Bevy's deferred lighting pass with Penumbra's shader and group 2
/// (on a deferred MSAA view: `msaa_render::draw_msaa_lighting`).
#[allow(clippy::type_complexity, reason = "a Bevy system")]
pub(crate) fn penumbra_lighting(
    view: ViewQuery<(
        &MeshViewBindGroup,
        &ViewTarget,
        Option<&DeferredLightingIdDepthTexture>,
        Option<&DeferredMsaaTextures>,
        &PenumbraLightingPipelineId,
        &PenumbraLightingBindGroup,
    )>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (mesh_view_bind_group, target, lighting_id_depth, msaa, pipeline_ids, group) =
        view.into_inner();
    let Some((bind_group, _)) = &group.bind_group else {
        return;
    };
    if let (Some(textures), Some(ids)) = (msaa, &pipeline_ids.msaa) {
        msaa_render::draw_msaa_lighting(
            &mut ctx,
            &pipeline_cache,
            mesh_view_bind_group,
            target,
            textures,
            ids,
            bind_group,
        );
        return;
    }
    let (Some(lighting_id_depth), Some(id)) = (lighting_id_depth, pipeline_ids.single) else {
        return;
    };
    let Some(pipeline) = pipeline_cache.get_render_pipeline(id) else {
        return; // compiling
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some("penumbra_lighting"),
        color_attachments: &[Some(target.get_color_attachment())],
        depth_stencil_attachment: Some(RenderPassDepthStencilAttachment {
            view: &lighting_id_depth.texture.default_view,
            depth_ops: Some(Operations {
                load: LoadOp::Load,
                store: StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_render_pipeline(pipeline);
    set_lighting_bind_groups(&mut pass, mesh_view_bind_group, bind_group);
    let pass_span = diagnostics.pass_span(&mut pass, "penumbra_lighting");
    pass.draw(0..3, 0..1);
    pass_span.end(&mut pass);
}
