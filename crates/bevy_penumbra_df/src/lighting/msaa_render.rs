//! Render-world side of deferred 4× MSAA (`lighting::msaa`): the multisampled
//! G-buffer and its swap into Bevy's deferred prepass, the classification pass, and the
//! two stencil-tested lighting draws.

use super::PenumbraLightingView;
use super::render::{
    PenumbraLightingBindGroup, PenumbraLightingPipelineId, set_lighting_bind_groups,
};
use bevy::core_pipeline::deferred::copy_lighting_id::DeferredLightingIdDepthTexture;
use bevy::core_pipeline::deferred::{DEFERRED_LIGHTING_PASS_ID_FORMAT, DEFERRED_PREPASS_FORMAT};
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::pbr::MeshViewBindGroup;
use bevy::prelude::*;
use bevy::render::camera::ExtractedCamera;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::{
    ColorTargetState, ColorWrites, CompareFunction, DepthStencilState, Extent3d, LoadOp,
    MultisampleState, Operations, PipelineCache, RenderPassColorAttachment,
    RenderPassDepthStencilAttachment, RenderPassDescriptor, RenderPipelineDescriptor,
    StencilFaceState, StencilOperation, StencilState, StoreOp, TextureDescriptor, TextureDimension,
    TextureFormat, TextureUsages, TextureView,
};
use bevy::render::renderer::{RenderAdapter, RenderContext, RenderDevice, ViewQuery};
use bevy::render::texture::{CachedTexture, ColorAttachment, TextureCache};
use bevy::render::view::ViewTarget;

/// Samples per pixel of deferred MSAA.
pub(crate) const MSAA_SAMPLES: u32 = 4;
/// The multisampled stencil marking how each pixel is shaded.
const STENCIL_FORMAT: TextureFormat = TextureFormat::Stencil8;
/// The pixels' classes (0 none, 1 once, 2 per sample).
const CLASS_FORMAT: TextureFormat = TextureFormat::R8Uint;
/// The representative depth the distance-field passes read.
const PIXEL_DEPTH_FORMAT: TextureFormat = TextureFormat::Depth32Float;
/// Stencil values (and references) of the two shaded classes.
const STENCIL_ONCE: u32 = 1;
const STENCIL_PER_SAMPLE: u32 = 2;

/// `None` when this renderer multisamples Bevy's G-buffer 4×, else why not.
pub(crate) fn support(world: &World) -> Option<String> {
    use bevy::render::render_resource::WgpuFeatures;
    let (Some(adapter), Some(device)) = (
        world.get_resource::<RenderAdapter>(),
        world.get_resource::<RenderDevice>(),
    ) else {
        return Some("there is no renderer".into());
    };
    if !device
        .features()
        .contains(WgpuFeatures::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES)
    {
        return Some(
            "the device lacks TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES (Bevy's G-buffer format \
             multisamples only with it)"
                .into(),
        );
    }
    let flags = adapter
        .get_texture_format_features(DEFERRED_PREPASS_FORMAT)
        .flags;
    if !flags.sample_count_supported(MSAA_SAMPLES) {
        return Some(format!(
            "this GPU cannot multisample the G-buffer format {DEFERRED_PREPASS_FORMAT:?} 4×"
        ));
    }
    None
}

/// Which draw of the lighting pass a pipeline is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightingVariant {
    /// Without MSAA: every pixel once, depth-tested against Bevy's lighting-id texture.
    Single,
    /// Classification to the single-sample class, G-buffer and depth targets.
    Classify,
    /// Stencil 1 on pixels shaded once.
    MarkPixels,
    /// Stencil 2 on pixels shaded per sample.
    MarkEdges,
    /// Lighting once per pixel where the stencil is 1.
    PerPixel,
    /// Lighting per sample where the stencil is 2.
    PerSample,
}

/// The MSAA variants, in the order `PenumbraLightingPipelineId::msaa` holds them.
pub(crate) const MSAA_VARIANTS: [LightingVariant; 5] = [
    LightingVariant::Classify,
    LightingVariant::MarkPixels,
    LightingVariant::MarkEdges,
    LightingVariant::PerPixel,
    LightingVariant::PerSample,
];

fn stencil(compare: CompareFunction, pass_op: StencilOperation, write_mask: u32) -> StencilState {
    let face = StencilFaceState {
        compare,
        fail_op: StencilOperation::Keep,
        depth_fail_op: StencilOperation::Keep,
        pass_op,
    };
    StencilState {
        front: face,
        back: face,
        read_mask: 0xff,
        write_mask,
    }
}

/// Turns the lighting pipeline `desc` (Bevy's view layouts, Penumbra's MSAA group 2,
/// `PENUMBRA_MSAA` defined) into `variant`'s.
pub(crate) fn specialize_variant(
    desc: &mut RenderPipelineDescriptor,
    variant: LightingVariant,
    classify_shader: &Handle<Shader>,
) {
    let fragment = desc.fragment.as_mut().expect("the lighting pass has one");
    let target = fragment.targets[0].clone().expect("one colour target");
    let multisample = MultisampleState {
        count: MSAA_SAMPLES,
        ..default()
    };
    let no_colour = ColorTargetState {
        write_mask: ColorWrites::empty(),
        ..target.clone()
    };
    let (entry, label) = match variant {
        LightingVariant::Single => return,
        LightingVariant::Classify => ("classify", "penumbra_msaa_classify_pipeline"),
        LightingVariant::MarkPixels => ("mark_pixels", "penumbra_msaa_mark_pixels_pipeline"),
        LightingVariant::MarkEdges => ("mark_edges", "penumbra_msaa_mark_edges_pipeline"),
        LightingVariant::PerPixel => ("fragment_msaa_pixel", "penumbra_msaa_lighting_pipeline"),
        LightingVariant::PerSample => (
            "fragment_msaa_sample",
            "penumbra_msaa_lighting_per_sample_pipeline",
        ),
    };
    desc.label = Some(label.into());
    fragment.entry_point = Some(entry.into());
    match variant {
        LightingVariant::Classify => {
            fragment.shader = classify_shader.clone();
            fragment.targets = vec![
                Some(CLASS_FORMAT.into()),
                Some(DEFERRED_PREPASS_FORMAT.into()),
            ];
            desc.depth_stencil = Some(DepthStencilState {
                format: PIXEL_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(CompareFunction::Always),
                stencil: default(),
                bias: default(),
            });
        }
        LightingVariant::MarkPixels | LightingVariant::MarkEdges => {
            fragment.shader = classify_shader.clone();
            fragment.targets = vec![Some(no_colour)];
            desc.depth_stencil = Some(DepthStencilState::stencil(
                STENCIL_FORMAT,
                stencil(CompareFunction::Always, StencilOperation::Replace, 0xff),
            ));
            desc.multisample = multisample;
        }
        LightingVariant::PerPixel | LightingVariant::PerSample => {
            desc.depth_stencil = Some(DepthStencilState::stencil(
                STENCIL_FORMAT,
                stencil(CompareFunction::Equal, StencilOperation::Keep, 0),
            ));
            desc.multisample = multisample;
        }
        LightingVariant::Single => {}
    }
}

/// A deferred MSAA view's textures (pooled in Bevy's `TextureCache`). Passes that work
/// per pixel read its representative G-buffer and depth.
#[derive(Component)]
pub struct DeferredMsaaTextures {
    /// Bevy's G-buffer words, 4×: swapped with Bevy's single-sample texture in
    /// `ViewPrepassTextures` while the deferred prepass renders.
    gbuffer: Option<ColorAttachment>,
    /// The lighting pass id, 4× (swapped likewise).
    lighting_id: Option<ColorAttachment>,
    /// The multisampled G-buffer's view (kept while it is swapped out).
    pub gbuffer_view: TextureView,
    /// The multisampled lighting id's view (likewise).
    pub lighting_id_view: TextureView,
    /// How each pixel is shaded, 4× stencil.
    stencil: CachedTexture,
    /// The pixels' classes.
    pub class: CachedTexture,
    /// The representative G-buffer texel and depth of each pixel (for the passes that
    /// trace per pixel: distance-field shadows, DFAO).
    pub pixel_gbuffer: CachedTexture,
    /// The representative depth (`Depth32Float`, reverse Z) of each pixel.
    pub pixel_depth: CachedTexture,
}

/// The single-sample depth and G-buffer the per-pixel passes read: the representative
/// ones on a deferred MSAA view, Bevy's otherwise.
pub fn pixel_prepass<'a>(
    prepass: &'a ViewPrepassTextures,
    msaa: Option<&'a DeferredMsaaTextures>,
) -> (Option<&'a TextureView>, Option<&'a TextureView>) {
    match msaa {
        Some(m) => (
            Some(&m.pixel_depth.default_view),
            Some(&m.pixel_gbuffer.default_view),
        ),
        None => (prepass.depth_view(), prepass.deferred_view()),
    }
}

fn cached(
    cache: &mut TextureCache,
    device: &RenderDevice,
    label: &'static str,
    size: Extent3d,
    sample_count: u32,
    format: TextureFormat,
    usage: TextureUsages,
) -> CachedTexture {
    cache.get(
        device,
        TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count,
            dimension: TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        },
    )
}

/// Makes each deferred MSAA view's textures, and takes Bevy's lighting-id copy target
/// away from it (the copy would read the multisampled id through a single-sample
/// binding; the classification replaces it).
pub(crate) fn prepare_deferred_msaa_textures(
    mut commands: Commands,
    mut cache: ResMut<TextureCache>,
    device: Res<RenderDevice>,
    views: Query<(Entity, &ExtractedCamera, &PenumbraLightingView)>,
) {
    for (entity, camera, view) in &views {
        let mut entity_commands = commands.entity(entity);
        let Some(size) = camera.physical_target_size.filter(|_| view.msaa.is_some()) else {
            entity_commands.remove::<DeferredMsaaTextures>();
            continue;
        };
        let size = Extent3d {
            width: size.x,
            height: size.y,
            depth_or_array_layers: 1,
        };
        let target = TextureUsages::RENDER_ATTACHMENT | TextureUsages::TEXTURE_BINDING;
        let mut make = |label, samples, format, usage| {
            cached(&mut cache, &device, label, size, samples, format, usage)
        };
        let gbuffer = make(
            "penumbra_msaa_gbuffer",
            MSAA_SAMPLES,
            DEFERRED_PREPASS_FORMAT,
            target,
        );
        let lighting_id = make(
            "penumbra_msaa_lighting_id",
            MSAA_SAMPLES,
            DEFERRED_LIGHTING_PASS_ID_FORMAT,
            target,
        );
        let stencil = make(
            "penumbra_msaa_stencil",
            MSAA_SAMPLES,
            STENCIL_FORMAT,
            TextureUsages::RENDER_ATTACHMENT,
        );
        let class = make("penumbra_msaa_class", 1, CLASS_FORMAT, target);
        let pixel_gbuffer = make(
            "penumbra_msaa_pixel_gbuffer",
            1,
            DEFERRED_PREPASS_FORMAT,
            target,
        );
        let pixel_depth = make("penumbra_msaa_pixel_depth", 1, PIXEL_DEPTH_FORMAT, target);
        let black = Some(LinearRgba::BLACK.into());
        entity_commands
            .insert(DeferredMsaaTextures {
                gbuffer_view: gbuffer.default_view.clone(),
                lighting_id_view: lighting_id.default_view.clone(),
                gbuffer: Some(ColorAttachment::new(gbuffer, None, None, black)),
                lighting_id: Some(ColorAttachment::new(lighting_id, None, None, black)),
                stencil,
                class,
                pixel_gbuffer,
                pixel_depth,
            })
            .remove::<DeferredLightingIdDepthTexture>();
    }
}

/// The multisampled G-buffer and Bevy's single-sample one trade places in
/// `ViewPrepassTextures`.
fn swap_gbuffers(prepass: &mut ViewPrepassTextures, msaa: &mut DeferredMsaaTextures) {
    std::mem::swap(&mut prepass.deferred, &mut msaa.gbuffer);
    std::mem::swap(
        &mut prepass.deferred_lighting_pass_id,
        &mut msaa.lighting_id,
    );
}

/// Before the prepasses: Bevy's deferred prepass renders into the multisampled G-buffer.
pub(crate) fn swap_in_msaa_gbuffer(
    view: ViewQuery<(&mut ViewPrepassTextures, &mut DeferredMsaaTextures)>,
) {
    let (mut prepass, mut msaa) = view.into_inner();
    swap_gbuffers(&mut prepass, &mut msaa);
}

/// After the prepasses: Bevy's single-sample textures are back (what later passes and
/// bind groups expect).
pub(crate) fn swap_out_msaa_gbuffer(
    view: ViewQuery<(&mut ViewPrepassTextures, &mut DeferredMsaaTextures)>,
) {
    let (mut prepass, mut msaa) = view.into_inner();
    swap_gbuffers(&mut prepass, &mut msaa);
}

/// The classification pass: class, representative G-buffer and depth per pixel.
pub(crate) fn classify_deferred_msaa(
    view: ViewQuery<(
        &MeshViewBindGroup,
        &DeferredMsaaTextures,
        &PenumbraLightingPipelineId,
        &PenumbraLightingBindGroup,
    )>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (mesh_view, textures, pipelines, group) = view.into_inner();
    let (Some(ids), Some(bind_group)) = (&pipelines.msaa, group.classify_bind_group()) else {
        return;
    };
    let Some(pipeline) = pipeline_cache.get_render_pipeline(ids[0]) else {
        return; // compiling
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    fn clear(view: &TextureView) -> Option<RenderPassColorAttachment<'_>> {
        Some(RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: Operations {
                load: LoadOp::Clear(default()),
                store: StoreOp::Store,
            },
        })
    }
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some("penumbra_msaa_classify"),
        color_attachments: &[
            clear(&textures.class.default_view),
            clear(&textures.pixel_gbuffer.default_view),
        ],
        depth_stencil_attachment: Some(RenderPassDepthStencilAttachment {
            view: &textures.pixel_depth.default_view,
            depth_ops: Some(Operations {
                load: LoadOp::Clear(0.0),
                store: StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    let span = diagnostics.pass_span(&mut pass, "penumbra_msaa_classify");
    pass.set_render_pipeline(pipeline);
    set_lighting_bind_groups(&mut pass, mesh_view, bind_group);
    pass.draw(0..3, 0..1);
    span.end(&mut pass);
}

/// The lighting pass of a deferred MSAA view: stencil marks, then lighting per pixel
/// and per sample.
pub(crate) fn draw_msaa_lighting(
    ctx: &mut RenderContext,
    pipeline_cache: &PipelineCache,
    mesh_view: &MeshViewBindGroup,
    target: &ViewTarget,
    textures: &DeferredMsaaTextures,
    ids: &[bevy::render::render_resource::CachedRenderPipelineId; 5],
    bind_group: &bevy::render::render_resource::BindGroup,
) {
    let Some(pipelines) = ids[1..]
        .iter()
        .map(|id| pipeline_cache.get_render_pipeline(*id))
        .collect::<Option<Vec<_>>>()
    else {
        return; // compiling
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let color = super::unresolved_color_attachment(target);
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some("penumbra_lighting"),
        color_attachments: &[Some(color)],
        depth_stencil_attachment: Some(RenderPassDepthStencilAttachment {
            view: &textures.stencil.default_view,
            depth_ops: None,
            stencil_ops: Some(Operations {
                load: LoadOp::Clear(0),
                store: StoreOp::Discard,
            }),
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    let span = diagnostics.pass_span(&mut pass, "penumbra_lighting");
    set_lighting_bind_groups(&mut pass, mesh_view, bind_group);
    let references = [
        STENCIL_ONCE,
        STENCIL_PER_SAMPLE,
        STENCIL_ONCE,
        STENCIL_PER_SAMPLE,
    ];
    for (pipeline, reference) in pipelines.into_iter().zip(references) {
        pass.set_render_pipeline(pipeline);
        pass.set_stencil_reference(reference);
        pass.draw(0..3, 0..1);
    }
    span.end(&mut pass);
}
