//! Render-world side of the particles: per emitter a pooled step uniform and bind
//! group, this frame's emitted particles written into their slots, and the step pass
//! in the `RenderGraph` schedule after the global field's compose pass (so it reads
//! this frame's clipmaps), before the cameras draw.

use super::{DistanceFieldParticles, DistanceFieldParticlesState};
use crate::global_field::{GlobalDistanceField, ViewGlobalField, empty_read_group, read_layout};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::math::DVec3;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{storage_buffer_sized, uniform_buffer_sized};
use bevy::render::render_resource::encase::UniformBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, PipelineCache,
    ShaderStages, ShaderType,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::storage::{GpuShaderBuffer, ShaderBuffer};
use bevy::render::sync_component::SyncComponent;
use bevy::render::sync_world::RenderEntity;
use bevy::render::{Extract, ExtractSchedule, Render, RenderApp, RenderStartup, RenderSystems};
use penumbra_df_core::particles::{GpuParticle, ParticleStep};

/// An emitter's frame as extracted.
#[derive(Component, Clone, Debug)]
pub struct ExtractedParticles {
    buffer: AssetId<ShaderBuffer>,
    step: ParticleStep,
    origin: Vec3,
    emitted: Vec<(u32, GpuParticle)>,
}

impl SyncComponent for DistanceFieldParticles {
    /// The render world's state goes with the component.
    type Target = (ExtractedParticles, GpuParticles);
}

impl ExtractComponent for DistanceFieldParticles {
    type QueryData = &'static DistanceFieldParticlesState;
    type QueryFilter = ();
    type Out = ExtractedParticles;

    fn extract_component(state: &DistanceFieldParticlesState) -> Option<ExtractedParticles> {
        let s = &state.settings;
        Some(ExtractedParticles {
            buffer: state.buffer.id(),
            step: ParticleStep {
                gravity: s.gravity,
                dt: state.dt,
                origin: Vec3::ZERO,
                restitution: s.restitution,
                friction: s.friction,
                radius: s.radius,
                count: s.capacity,
            },
            origin: state.origin,
            emitted: state.emitted.clone(),
        })
    }
}

/// The camera whose global field the particles collide with: its render entity and
/// position (the first active one with a field, in entity order).
#[derive(Resource, Default)]
struct ParticleFieldCamera(Option<(Entity, Vec3)>);

/// An emitter's GPU state (pooled).
#[derive(Component)]
pub struct GpuParticles {
    params: Buffer,
    group: Option<(BindGroup, BufferId)>,
    /// This frame's workgroups (0: not stepped).
    dispatch: u32,
    /// The field's bind group this frame.
    field: Option<BindGroup>,
}

#[derive(Resource)]
struct ParticlePipelines {
    layout: BindGroupLayoutDescriptor,
    step: CachedComputePipelineId,
}

/// An empty field, for emitters without a field camera (made when first needed).
#[derive(Resource, Default)]
struct NoParticleField(Option<BindGroup>);

/// Render-world systems of the particles.
#[derive(SystemSet, Clone, Debug, PartialEq, Eq, Hash)]
pub enum ParticleSystems {
    /// The step pass.
    Step,
}

pub(super) fn build(app: &mut App) {
    app.add_plugins(ExtractComponentPlugin::<DistanceFieldParticles>::default());
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render_app
        .init_resource::<ParticleFieldCamera>()
        .init_resource::<NoParticleField>()
        .add_systems(ExtractSchedule, timed(extract_particle_field_camera))
        .add_systems(
            Render,
            timed(prepare_particles)
                .in_set(RenderSystems::PrepareBindGroups)
                .after(crate::global_field::render::prepare_global_field_bind_groups),
        )
        .add_systems(
            RenderGraph,
            timed(step_particles)
                .in_set(ParticleSystems::Step)
                .after(crate::global_field::compose_global_fields)
                .in_set(bevy::render::renderer::RenderGraphSystems::Render)
                .before(camera_driver),
        );
}

pub(super) fn finish(app: &mut App) {
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app.add_systems(RenderStartup, init_particle_pipelines);
    }
}

fn init_particle_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return;
    };
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_particles_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_sized(false, None),
                uniform_buffer_sized(false, Some(ParticleStep::min_size())),
            ),
        ),
    );
    let step = library.queue_compute_layouts(
        &pipeline_cache,
        "penumbra_particles_step",
        &[layout.clone(), read_layout()],
        "df/particles.wgsl",
        "step_particles",
    );
    commands.insert_resource(ParticlePipelines { layout, step });
}

type FieldCameraItem = (
    Entity,
    &'static RenderEntity,
    &'static Camera,
    &'static GlobalTransform,
);

fn extract_particle_field_camera(
    mut field: ResMut<ParticleFieldCamera>,
    cameras: Extract<Query<FieldCameraItem, With<GlobalDistanceField>>>,
) {
    field.0 = cameras
        .iter()
        .filter(|(_, _, camera, _)| camera.is_active)
        .min_by_key(|(entity, ..)| *entity)
        .map(|(_, render, _, transform)| (render.id(), transform.translation()));
}

/// Writes each emitter's emitted particles and step uniform, and (re)makes its bind
/// group when its buffer changes.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_particles(
    mut commands: Commands,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipeline_cache: Res<PipelineCache>,
    pipelines: Option<Res<ParticlePipelines>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    field_camera: Res<ParticleFieldCamera>,
    fields: Query<&ViewGlobalField>,
    mut no_field: ResMut<NoParticleField>,
    mut emitters: Query<(Entity, &ExtractedParticles, Option<&mut GpuParticles>)>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    let ready = pipeline_cache
        .get_compute_pipeline(pipelines.step)
        .is_some();
    let (field, camera) = match field_camera
        .0
        .and_then(|(e, at)| fields.get(e).ok().map(|f| (f.read_group().clone(), at)))
    {
        Some(found) => found,
        None => (
            no_field
                .0
                .get_or_insert_with(|| empty_read_group(&allocations, &device, &pipeline_cache))
                .clone(),
            Vec3::ZERO,
        ),
    };
    for (entity, extracted, gpu) in &mut emitters {
        let Some(particles) = buffers.get(extracted.buffer) else {
            continue; // not uploaded yet
        };
        let mut fresh = None;
        let gpu = match gpu {
            Some(g) => g.into_inner(),
            None => fresh.insert(GpuParticles {
                params: allocations.sized_buffer(
                    &device,
                    "penumbra_particles_step",
                    ParticleStep::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                group: None,
                dispatch: 0,
                field: None,
            }),
        };
        // Emitted particles: one write per contiguous run of slots.
        let size = GpuParticle::min_size().get();
        let mut i = 0;
        while i < extracted.emitted.len() {
            let first = extracted.emitted[i].0;
            let mut run = vec![extracted.emitted[i].1];
            while i + run.len() < extracted.emitted.len()
                && extracted.emitted[i + run.len()].0 == first + run.len() as u32
            {
                run.push(extracted.emitted[i + run.len()].1);
            }
            let mut bytes = bevy::render::render_resource::encase::StorageBuffer::new(Vec::new());
            bytes.write(&run).expect("encodes");
            queue.write_buffer(&particles.buffer, u64::from(first) * size, bytes.as_ref());
            i += run.len();
        }
        let step = ParticleStep {
            origin: (extracted.origin.as_dvec3() - DVec3::from(camera)).as_vec3(),
            ..extracted.step
        };
        let mut bytes = UniformBuffer::new(Vec::new());
        bytes.write(&step).expect("encodes");
        queue.write_buffer(&gpu.params, 0, bytes.as_ref());
        if gpu
            .group
            .as_ref()
            .is_none_or(|(_, id)| *id != particles.buffer.id())
        {
            let group = allocations.bind_group(
                &device,
                "penumbra_particles",
                &pipeline_cache.get_bind_group_layout(&pipelines.layout),
                &BindGroupEntries::sequential((
                    particles.buffer.as_entire_binding(),
                    gpu.params.as_entire_binding(),
                )),
            );
            gpu.group = Some((group, particles.buffer.id()));
        }
        gpu.field = Some(field.clone());
        gpu.dispatch = if ready && step.dt > 0.0 {
            step.count.div_ceil(64)
        } else {
            0
        };
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// The step pass: one dispatch per emitter. Dispatches only.
fn step_particles(
    mut ctx: RenderContext,
    emitters: Query<&GpuParticles>,
    pipelines: Option<Res<ParticlePipelines>>,
    pipeline_cache: Res<PipelineCache>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    if emitters.iter().all(|e| e.dispatch == 0) {
        return;
    }
    let Some(pipeline) = pipeline_cache.get_compute_pipeline(pipelines.step) else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_particles_step");
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_particles_step"),
            timestamp_writes: None,
        });
    pass.set_pipeline(pipeline);
    for emitter in &emitters {
        let (Some((group, _)), Some(field)) = (&emitter.group, &emitter.field) else {
            continue;
        };
        if emitter.dispatch == 0 {
            continue;
        }
        pass.set_bind_group(0, group, &[]);
        pass.set_bind_group(1, field, &[]);
        pass.dispatch_workgroups(emitter.dispatch, 1, 1);
    }
    drop(pass);
    time_span.end(ctx.command_encoder());
}
