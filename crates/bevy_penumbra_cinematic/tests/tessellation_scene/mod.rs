//! What the tessellation tests share: the test rock as a Bevy mesh, a height image, a
//! camera looking at the rock and the read-back of an entity's output totals.

#![allow(dead_code, reason = "each test uses part")]

use bevy::asset::RenderAssetUsages;
use bevy::image::Image;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_penumbra_cinematic::tessellation::{TessellationState, shape_mesh};
use penumbra_cinematic_core::tessellation::shapes::{ShapeMesh, height_map};

/// `shape` as a Bevy mesh, with or without its normals and UVs.
pub fn mesh_of(shape: &ShapeMesh, normals: bool, uvs: bool) -> Mesh {
    let mut mesh = shape_mesh(shape);
    if !normals {
        mesh.remove_attribute(Mesh::ATTRIBUTE_NORMAL);
    }
    if !uvs {
        mesh.remove_attribute(Mesh::ATTRIBUTE_UV_0);
    }
    mesh
}

/// The test height map (`shapes::height_map`), `size²`, as 32-bit floats.
pub fn height_image(size: u32) -> Image {
    let bytes: Vec<u8> = height_map(size)
        .iter()
        .flat_map(|h| h.to_le_bytes())
        .collect();
    Image::new(
        Extent3d {
            width: size,
            height: size,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        bytes,
        TextureFormat::R32Float,
        RenderAssetUsages::default(),
    )
}

/// A camera `distance` from the rock, a little above it.
pub fn camera(distance: f32) -> impl Bundle {
    (
        Camera3d::default(),
        Projection::Perspective(PerspectiveProjection {
            fov: 0.8,
            ..default()
        }),
        Transform::from_translation(Vec3::new(0.3, 0.6, 1.0).normalize() * distance)
            .looking_at(Vec3::new(0.0, 0.3, 0.0), Vec3::Y),
    )
}

/// The first tessellated entity's totals (bias, vertices, indices, patches), read back
/// every frame once it exists.
#[derive(Resource, Default)]
pub struct Totals(pub Option<Vec<u32>>);

/// Starts the totals' read-back (add with `Totals`).
pub fn read_totals(
    mut commands: Commands,
    states: Query<&TessellationState>,
    mut started: Local<bool>,
) {
    let Some(state) = states.iter().next() else {
        return;
    };
    if !*started {
        *started = true;
        commands
            .spawn(Readback::buffer(state.buffers()[3].clone()))
            .observe(|event: On<ReadbackComplete>, mut totals: ResMut<Totals>| {
                totals.0 = Some(
                    event
                        .data
                        .chunks_exact(4)
                        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
                        .collect(),
                );
            });
    }
}

/// Warm-up condition: every `Tessellated` entity's first tessellation came back (its
/// output mesh is shown from the next frame).
pub fn all_tessellated(world: &mut World) -> bool {
    let wanted = world
        .query_filtered::<(), With<bevy_penumbra_cinematic::Tessellated>>()
        .iter(world)
        .count();
    let done = world
        .query::<&TessellationState>()
        .iter(world)
        .filter(|s| s.latest_totals().is_some())
        .count();
    done == wanted
}
