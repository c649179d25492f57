//! Buffer dumps: what Penumbra's passes read, copied back to the CPU for checking against
//! independent ground truth (the scene viewer's `--dump`, `../shared/tools/*_truth.py`).
//!
//! Put [`PenumbraBufferDump`] on a [`PenumbraLighting`](crate::PenumbraLighting) camera:
//! every frame rendered while it is there, a compute pass after the main pass copies the
//! view's buffers into one GPU buffer, which is read back asynchronously; the newest
//! result arrives on the camera as [`PenumbraBuffers`] a frame or two later. Buffers, all
//! `f32`, `(height, width[, channels])`, row 0 at the top, one value per view pixel:
//!
//! - `depth`: the distance from the camera to the surface along the pixel-centre ray,
//!   metres (Euclidean, not view-space z); NaN for background.
//! - `normal` (3 channels): the world-space unit normal the passes read (Bevy's deferred
//!   G-buffer, octahedral 12+12 bits); NaN for background.
//! - `visibility_<light>`: one per distance-field-shadowed light, the mask layer the
//!   lighting pass reads (1 lit, 0 shadowed; the surface's own shadow, `n · l`, is in
//!   it); 1 for background. `<light>` is the light's `Name` (characters other than
//!   letters, digits, `-` and `_` become `_`), else its entity (`12v0`).
//!
//! - `ao` and `bent_normal` (3 channels), on a camera with
//!   [`DistanceFieldAmbientOcclusion`](crate::ao::DistanceFieldAmbientOcclusion): the
//!   full-resolution AO the lighting pass reads (1 open), before contrast and min
//!   occlusion, and the world-space unit bent normal; NaN for background.
//! - `ssao`, on a camera with Bevy's `ScreenSpaceAmbientOcclusion` and no DFAO: SSAO's
//!   spatially denoised visibility (1 open) as Bevy's lighting reads it; NaN for
//!   background. (With both, the DFAO planes are dumped.)
//! - `face_normal` (3 channels), on a camera with
//!   [`FaceNormalPrepass`](crate::face_normals::FaceNormalPrepass): the world-space unit
//!   normal of the triangle at the pixel centre, by its winding; NaN where no triangle
//!   was drawn.
//!
//! Cost: nothing without the component. With it: one compute pass and a copy of
//! `(4 + lights [+ 4 with AO] [+ 3 with face normals]) × 4` bytes per pixel each frame, and a buffer pair per camera, kept while
//! the size is unchanged. A frame whose previous read-back is still in flight is skipped.

mod render;

use crate::system_times::timed;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use std::sync::Mutex;
use std::sync::mpsc::Receiver;

/// Adds [`PenumbraBufferDump`]. Part of `PenumbraPlugins`; needs
/// [`crate::PenumbraLightingPlugin`].
#[derive(Default)]
pub struct PenumbraBufferDumpPlugin;

/// Asks for the buffers of every frame this camera renders (a `PenumbraLighting`
/// camera; others get nothing) as [`PenumbraBuffers`]. See the [module docs](self).
#[derive(Component, ExtractComponent, Reflect, Clone, Copy, Debug, Default)]
#[reflect(Component, Clone, Default)]
pub struct PenumbraBufferDump;

/// The newest dump of a camera's buffers (inserted on the camera).
#[derive(Component, Clone, Debug)]
pub struct PenumbraBuffers {
    /// Width and height in pixels.
    pub size: UVec2,
    /// The buffers, in the order of the [module docs](self).
    pub buffers: Vec<DumpedBuffer>,
}

impl PenumbraBuffers {
    /// The buffer called `name`.
    pub fn get(&self, name: &str) -> Option<&DumpedBuffer> {
        self.buffers.iter().find(|b| b.name == name)
    }
}

/// One dumped buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct DumpedBuffer {
    /// `depth`, `normal`, `visibility_<light>`, ….
    pub name: String,
    /// Values per pixel (1, or 3 for `normal`).
    pub channels: u32,
    /// `height × width × channels` values, row 0 at the top.
    pub data: Vec<f32>,
}

/// A read-back from the render world: camera, size, the lights of the mask layers, the
/// raw buffer (planes as in `buffer_dump.wgsl`).
struct RawDump {
    camera: Entity,
    size: UVec2,
    lights: Vec<Entity>,
    /// What the AO and bent-normal planes after the masks hold.
    ao: AoPlanes,
    /// Whether the face-normal planes follow them.
    face: bool,
    data: Vec<f32>,
}

/// The source of a dump's AO planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AoPlanes {
    /// None: the camera has no AO (the planes are absent or unwritten).
    None,
    /// Distance-field AO and its bent normal.
    Dfao,
    /// Bevy's SSAO (its visibility; the bent-normal planes hold nothing).
    Ssao,
}

/// The main world's end of the read-back channel.
#[derive(Resource)]
struct DumpReceiver(Mutex<Receiver<RawDump>>);

impl Plugin for PenumbraBufferDumpPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<crate::PenumbraLightingPlugin>(
            app,
            "PenumbraBufferDumpPlugin",
            "PenumbraLightingPlugin",
        );
        let (sender, receiver) = std::sync::mpsc::channel();
        app.register_type::<PenumbraBufferDump>()
            .add_plugins(ExtractComponentPlugin::<PenumbraBufferDump>::default())
            .insert_resource(DumpReceiver(Mutex::new(receiver)))
            .add_systems(
                First,
                timed(receive_dumps).after(bevy::ecs::message::MessageUpdateSystems),
            );
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app, sender);
        }
    }

    fn finish(&self, app: &mut App) {
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
        }
    }
}

/// The name of a light in its buffer's name (`visibility_<light>`): its `Name` made
/// file-safe, else its entity. (Two lights of one name: the second gets `_<entity>`.)
pub fn light_name(entity: Entity, name: Option<&Name>) -> String {
    match name {
        Some(n) if !n.as_str().is_empty() => n
            .as_str()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect(),
        _ => entity.to_string(),
    }
}

/// Turns read-backs into [`PenumbraBuffers`] on their cameras (the newest per camera).
fn receive_dumps(
    mut commands: Commands,
    receiver: Res<DumpReceiver>,
    names: Query<&Name>,
    cameras: Query<(), With<PenumbraBufferDump>>,
) {
    let Ok(receiver) = receiver.0.lock() else {
        return;
    };
    for raw in receiver.try_iter() {
        if !cameras.contains(raw.camera) {
            continue;
        }
        let buffers = unpack(&raw, |e| light_name(e, names.get(e).ok()));
        commands.entity(raw.camera).insert(PenumbraBuffers {
            size: raw.size,
            buffers,
        });
    }
}

/// Splits the raw planes into named buffers (background: NaN depth and normal).
fn unpack(raw: &RawDump, name: impl Fn(Entity) -> String) -> Vec<DumpedBuffer> {
    let n = (raw.size.x * raw.size.y) as usize;
    let plane = |k: usize, len: usize| raw.data.get(k..k + len).unwrap_or(&[]).to_vec();
    let mut depth = plane(0, n);
    let mut normal = plane(n, 3 * n);
    for (i, d) in depth.iter_mut().enumerate() {
        if *d < 0.0 {
            *d = f32::NAN;
            if let Some(v) = normal.get_mut(3 * i..3 * i + 3) {
                v.fill(f32::NAN);
            }
        }
    }
    let mut buffers = vec![
        DumpedBuffer {
            name: "depth".into(),
            channels: 1,
            data: depth,
        },
        DumpedBuffer {
            name: "normal".into(),
            channels: 3,
            data: normal,
        },
    ];
    let mut used: Vec<String> = Vec::new();
    for (l, &light) in raw.lights.iter().enumerate() {
        let mut label = name(light);
        if used.contains(&label) {
            label = format!("{label}_{light}");
        }
        used.push(label.clone());
        buffers.push(DumpedBuffer {
            name: format!("visibility_{label}"),
            channels: 1,
            data: plane((4 + l) * n, n),
        });
    }
    if raw.ao != AoPlanes::None {
        let base = (4 + raw.lights.len()) * n;
        let mut ao = plane(base, n);
        let mut bent = plane(base + n, 3 * n);
        for (i, d) in buffers[0].data.iter().enumerate() {
            if d.is_nan() {
                if let Some(a) = ao.get_mut(i) {
                    *a = f32::NAN;
                }
                if let Some(v) = bent.get_mut(3 * i..3 * i + 3) {
                    v.fill(f32::NAN);
                }
            }
        }
        if raw.ao == AoPlanes::Ssao {
            buffers.push(DumpedBuffer {
                name: "ssao".into(),
                channels: 1,
                data: ao,
            });
        } else {
            buffers.push(DumpedBuffer {
                name: "ao".into(),
                channels: 1,
                data: ao,
            });
            buffers.push(DumpedBuffer {
                name: "bent_normal".into(),
                channels: 3,
                data: bent,
            });
        }
    }
    if raw.face {
        let base = (4 + raw.lights.len() + if raw.ao == AoPlanes::None { 0 } else { 4 }) * n;
        let mut face = plane(base, 3 * n);
        // No triangle drawn (the background, or only undrawn meshes): NaN.
        for v in face.chunks_exact_mut(3) {
            if v.iter().all(|&c| c == 0.0) {
                v.fill(f32::NAN);
            }
        }
        buffers.push(DumpedBuffer {
            name: "face_normal".into(),
            channels: 3,
            data: face,
        });
    }
    buffers
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unpack_splits_planes_marks_background_and_names_lights() {
        let sun = Entity::from_raw_u32(7).unwrap();
        let lamp = Entity::from_raw_u32(9).unwrap();
        // 2×1 pixels: pixel 0 background, pixel 1 a surface; two lights.
        let raw = RawDump {
            camera: Entity::PLACEHOLDER,
            size: UVec2::new(2, 1),
            lights: vec![sun, lamp],
            ao: AoPlanes::Dfao,
            face: false,
            data: vec![
                -1.0, 3.5, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.25, 1.0,
                0.5, // depth … masks
                1.0, 0.75, 0.0, 0.0, 0.0, 0.6, 0.8, 0.0, // AO, bent normal
            ],
        };
        // Both named "Sun": the second gets its entity appended.
        let b = unpack(&raw, |_| "Sun".into());
        let names: Vec<_> = b.iter().map(|b| b.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "depth",
                "normal",
                "visibility_Sun",
                &format!("visibility_Sun_{lamp}"),
                "ao",
                "bent_normal"
            ]
        );
        assert!(b[0].data[0].is_nan() && b[0].data[1] == 3.5);
        assert!(b[1].data[..3].iter().all(|v| v.is_nan()));
        assert_eq!(&b[1].data[3..], &[0.0, 1.0, 0.0]);
        assert_eq!(b[2].data, [1.0, 0.25]);
        assert_eq!(b[3].data, [1.0, 0.5]);
        assert!(b[4].data[0].is_nan() && b[4].data[1] == 0.75);
        assert!(b[5].data[..3].iter().all(|v| v.is_nan()));
        assert_eq!(&b[5].data[3..], &[0.6, 0.8, 0.0]);
        // The same planes from SSAO: one `ssao` buffer, no bent normal.
        let ssao = unpack(
            &RawDump {
                ao: AoPlanes::Ssao,
                ..raw
            },
            |_| "Sun".into(),
        );
        assert_eq!(ssao.len(), 5);
        assert_eq!(ssao[4].name, "ssao");
        assert!(ssao[4].data[0].is_nan() && ssao[4].data[1] == 0.75);
        assert_eq!(light_name(sun, Some(&Name::new("a b/c"))), "a_b_c");
        assert_eq!(light_name(sun, None), sun.to_string());
    }
}
