//! A tessellated mesh that is also a distance-field caster keeps its distance field
//! baked from the source mesh (`CasterMesh`), not from the output pool the entity draws
//! (a placeholder of zeros on the CPU): its SDF bakes, and DF shadows see the rock.

use bevy::prelude::*;
use penumbra::cinematic::tessellation::{TessellationState, shape_mesh};
use penumbra::df::{CasterMesh, DistanceFieldCaster, SdfBakeRequest, SdfBaked};
use penumbra::prelude::*;
use penumbra_cinematic_core::tessellation::shapes::rock;
use penumbra_test::{HeadlessRender, gpu_or_skip};

#[derive(Resource)]
struct Rock(Entity, Handle<Mesh>);

#[test]
fn a_tessellated_caster_bakes_its_source() {
    if !gpu_or_skip("a_tessellated_caster_bakes_its_source") {
        return;
    }
    // Until the pool is shown and the SDF is baked.
    let harness = HeadlessRender::new(64, 64).frames(2).warm_up(|world| {
        let Some(entity) = world.get_resource::<Rock>().map(|r| r.0) else {
            return false;
        };
        world.get::<SdfBaked>(entity).is_some()
            && world.get::<TessellationState>(entity).is_some_and(|s| {
                world
                    .get::<Mesh3d>(entity)
                    .is_some_and(|m| m.0 == *s.output())
            })
    });
    let mut app = harness.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred())
        .add_systems(
            Startup,
            |mut commands: Commands,
             mut meshes: ResMut<Assets<Mesh>>,
             mut materials: ResMut<Assets<StandardMaterial>>| {
                let source = meshes.add(shape_mesh(&rock(16, 6)));
                let rock = commands
                    .spawn((
                        Mesh3d(source.clone()),
                        MeshMaterial3d(materials.add(StandardMaterial::default())),
                        Tessellated::default(),
                        DistanceFieldCaster::default(),
                    ))
                    .id();
                commands.insert_resource(Rock(rock, source));
                commands.spawn((
                    DirectionalLight::default(),
                    DistanceFieldShadows::default(),
                    Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
                commands.spawn((
                    Camera3d::default(),
                    PenumbraLighting,
                    Transform::from_xyz(0.0, 1.5, 3.0)
                        .looking_at(Vec3::new(0.0, 0.3, 0.0), Vec3::Y),
                ));
            },
        );
    let (_, app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world();
    let Rock(entity, source) = world.resource::<Rock>();
    assert_eq!(world.get::<CasterMesh>(*entity).map(|c| &c.0), Some(source));
    assert_eq!(
        &world.get::<SdfBakeRequest>(*entity).expect("a bake").mesh,
        source
    );
    assert_ne!(
        world.get::<Mesh3d>(*entity).unwrap().0,
        *source,
        "the pool is drawn"
    );
}
