//! Penumbra's diagnostics, read back from Bevy's `DiagnosticsStore` in a headless app:
//! the scene figures (`penumbra/df/*`: objects, frustum-visible and culled objects,
//! atlas bytes, uploads, pending bakes) and the passes' time spans through Bevy's
//! `RenderDiagnosticsPlugin` (`render/penumbra_*/elapsed_{cpu,gpu}`).

use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy::render::diagnostic::RenderDiagnosticsPlugin;
use penumbra::df::PenumbraDiagnosticsPlugin;
use penumbra::df::diagnostics::{
    ATLAS_BUDGET_BYTES, ATLAS_BYTES, ATLAS_USED_BYTES, BAKES_PENDING, CULLED_OBJECTS, OBJECTS,
    SKIPPED_OBJECTS, UPLOADED_BYTES, VISIBLE_OBJECTS,
};
use penumbra::prelude::*;
use penumbra_test::{HeadlessRender, gpu_or_skip};

fn scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let grey = materials.add(Color::srgb(0.7, 0.7, 0.7));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(10.0, 10.0))),
        MeshMaterial3d(grey.clone()),
    ));
    // Two analytic casters in view, one behind the camera.
    for (x, z) in [(-1.0, 0.0), (1.0, 0.0), (0.0, 12.0)] {
        commands.spawn((
            Mesh3d(meshes.add(Sphere::new(0.5))),
            MeshMaterial3d(grey.clone()),
            Transform::from_xyz(x, 0.5, z),
            DistanceFieldCaster {
                source: CasterSource::Sphere { radius: 0.5 },
                ..default()
            },
        ));
    }
    commands.spawn((
        DirectionalLight {
            illuminance: 8_000.0,
            ..default()
        },
        DistanceFieldShadows::default(),
        Transform::default().looking_to(Vec3::new(-0.4, -1.0, -0.3), Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Transform::from_xyz(0.0, 3.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

#[test]
fn diagnostics_report_scene_figures_and_pass_times() {
    if !gpu_or_skip("diagnostics_report_scene_figures_and_pass_times") {
        return;
    }
    let render = HeadlessRender::new(64, 64).frames(6);
    let mut app = render.app();
    app.add_plugins((
        PenumbraPlugins,
        PenumbraDiagnosticsPlugin,
        RenderDiagnosticsPlugin,
    ))
    .insert_resource(DefaultOpaqueRendererMethod::deferred())
    .add_systems(Startup, scene);
    let (_, app) = render.run_keeping_app(app).expect("headless render");
    let store = app.world().resource::<DiagnosticsStore>();
    let value = |path: &DiagnosticPath| {
        store
            .get(path)
            .and_then(|d| d.value())
            .unwrap_or_else(|| panic!("no value for {path}"))
    };
    assert_eq!(value(&OBJECTS), 3.0);
    assert_eq!(
        value(&VISIBLE_OBJECTS),
        2.0,
        "the sphere behind the camera is culled"
    );
    assert_eq!(value(&CULLED_OBJECTS), 1.0);
    assert_eq!(value(&SKIPPED_OBJECTS), 0.0);
    assert_eq!(value(&BAKES_PENDING), 0.0);
    // Analytic casters: no SDF in the atlas; a static scene uploads nothing.
    assert_eq!(value(&ATLAS_USED_BYTES), 0.0);
    assert_eq!(value(&ATLAS_BYTES), 0.0);
    assert_eq!(value(&ATLAS_BUDGET_BYTES), (64u64 << 20) as f64);
    assert_eq!(value(&UPLOADED_BYTES), 0.0);
    // The passes' spans: GPU timestamps where the adapter has them (lavapipe does), CPU
    // spans always. (`penumbra_df_apply_deltas` runs only in frames with changes.)
    for span in ["penumbra_df_shadows", "penumbra_lighting"] {
        let cpu = DiagnosticPath::new(format!("render/{span}/elapsed_cpu"));
        let gpu = DiagnosticPath::new(format!("render/{span}/elapsed_gpu"));
        let time = store
            .get(&gpu)
            .or_else(|| store.get(&cpu))
            .and_then(|d| d.average())
            .unwrap_or_else(|| panic!("no time span for {span}"));
        assert!(time.is_finite() && time >= 0.0, "{span}: {time}");
    }
}
