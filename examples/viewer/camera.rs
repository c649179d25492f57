//! The viewer's camera: orbit (left drag), pan (right drag), zoom (wheel) about a target;
//! `F` toggles a fly camera (WASD, Q/E down/up, right drag to look, wheel for speed).
//! Input the egui panel uses is left to it.

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;

/// The camera's state: orbit about `target` at `distance`, or fly.
#[derive(Component, Clone, Debug)]
pub struct CameraRig {
    /// The orbit's centre.
    pub target: Vec3,
    /// The camera's distance from it.
    pub distance: f32,
    /// Rotation about +Y, radians.
    pub yaw: f32,
    /// Elevation, radians.
    pub pitch: f32,
    /// Flying instead of orbiting.
    pub fly: bool,
    /// Fly speed, units per second (starts at the distance per 2 s).
    pub speed: f32,
}

impl CameraRig {
    /// Orbiting `target` from `eye`.
    pub fn new(eye: Vec3, target: Vec3) -> Self {
        let offset = eye - target;
        let distance = offset.length().max(1e-3);
        Self {
            target,
            distance,
            yaw: offset.x.atan2(offset.z),
            pitch: (offset.y / distance).clamp(-1.0, 1.0).asin(),
            fly: false,
            speed: distance * 0.5,
        }
    }

    fn rotation(&self) -> Quat {
        Quat::from_euler(EulerRot::YXZ, self.yaw, -self.pitch, 0.0)
    }
}

/// Whether egui wants this frame's pointer or keyboard (set by the panel).
#[derive(Resource, Default)]
pub struct UiHasInput {
    /// The pointer is over the panel or dragging in it.
    pub pointer: bool,
    /// A text field has the keyboard.
    pub keyboard: bool,
}

/// The camera's input systems (windowed).
pub fn add_camera_controls(app: &mut App) {
    app.init_resource::<UiHasInput>()
        .add_systems(Update, drive_camera);
}

fn drive_camera(
    time: Res<Time>,
    keys: Res<ButtonInput<KeyCode>>,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    ui: Res<UiHasInput>,
    mut cameras: Query<(&mut CameraRig, &mut Transform)>,
) {
    for (mut rig, mut transform) in &mut cameras {
        if !ui.keyboard && keys.just_pressed(KeyCode::KeyF) {
            rig.fly = !rig.fly;
            if !rig.fly {
                // Back to orbiting the point in front of the camera.
                rig.target = transform.translation + transform.forward() * rig.distance;
            }
        }
        let pointer = !ui.pointer;
        let delta = motion.delta * 0.005;
        let button = if rig.fly {
            MouseButton::Right
        } else {
            MouseButton::Left
        };
        let look = pointer && buttons.pressed(button);
        if look {
            rig.yaw -= delta.x;
            rig.pitch = (rig.pitch + delta.y * if rig.fly { -1.0 } else { 1.0 }).clamp(-1.5, 1.5);
        }
        if rig.fly {
            if pointer && scroll.delta.y != 0.0 {
                rig.speed *= 1.1f32.powf(scroll.delta.y);
            }
            let rotation = rig.rotation();
            let mut step = Vec3::ZERO;
            if !ui.keyboard {
                for (key, dir) in [
                    (KeyCode::KeyW, Vec3::NEG_Z),
                    (KeyCode::KeyS, Vec3::Z),
                    (KeyCode::KeyA, Vec3::NEG_X),
                    (KeyCode::KeyD, Vec3::X),
                    (KeyCode::KeyQ, Vec3::NEG_Y),
                    (KeyCode::KeyE, Vec3::Y),
                ] {
                    if keys.pressed(key) {
                        step += rotation * dir;
                    }
                }
            }
            transform.translation += step * rig.speed * time.delta_secs();
            transform.rotation = rotation;
        } else {
            if pointer && scroll.delta.y != 0.0 {
                rig.distance *= 0.9f32.powf(scroll.delta.y);
            }
            if pointer && buttons.pressed(MouseButton::Right) {
                let pan = rig.rotation() * Vec3::new(-motion.delta.x, motion.delta.y, 0.0);
                let distance = rig.distance;
                rig.target += pan * distance * 0.0015;
            }
            let rotation = rig.rotation();
            transform.rotation = rotation;
            transform.translation = rig.target + rotation * Vec3::Z * rig.distance;
        }
    }
}
