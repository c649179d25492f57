//! The harness fails a run on a wgpu error: a render-world system that creates an
//! invalid buffer (mapped at creation, 3 bytes: not a multiple of 4, a validation error) makes
//! `run` return `HarnessError::Render` naming it, instead of a capture (Bevy's default
//! error handler quits the app, which a headless run only noticed as a read-back
//! timeout, or not at all).

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::{BufferDescriptor, BufferUsages};
use bevy::render::renderer::RenderDevice;
use bevy::render::{Render, RenderSystems};
use penumbra_test::{HarnessError, HeadlessRender, gpu_or_skip};

fn invalid_buffer(device: Res<RenderDevice>, mut done: Local<bool>) {
    if !*done {
        *done = true;
        device.create_buffer(&BufferDescriptor {
            label: Some("penumbra_test_invalid"),
            size: 3,
            usage: BufferUsages::COPY_DST,
            mapped_at_creation: true,
        });
    }
}

#[test]
fn a_wgpu_error_fails_the_run() {
    if !gpu_or_skip("a_wgpu_error_fails_the_run") {
        return;
    }
    let harness = HeadlessRender::new(16, 16).frames(3);
    let mut app = harness.app();
    app.add_systems(Startup, |mut commands: Commands| {
        commands.spawn(Camera3d::default());
    });
    app.sub_app_mut(RenderApp)
        .add_systems(Render, invalid_buffer.in_set(RenderSystems::Prepare));
    match harness.run(app) {
        Err(HarnessError::Render(errors)) => {
            println!("{errors:?}");
            // Once, though Bevy reports it every frame while rendering is stopped.
            assert_eq!(errors.len(), 1, "{errors:?}");
            assert!(errors[0].contains("penumbra_test_invalid"), "{errors:?}");
        }
        Err(e) => panic!("another error: {e}"),
        Ok(_) => panic!("the run passed"),
    }
    // The next run starts clean.
    let mut app = harness.app();
    app.add_systems(Startup, |mut commands: Commands| {
        commands.spawn(Camera3d::default());
    });
    assert!(harness.run(app).is_ok());
}
