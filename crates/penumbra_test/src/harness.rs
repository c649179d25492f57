//! [`HeadlessRender`]: a windowless Bevy app that renders into an image and reads it back.

use bevy::{
    camera::{ImageRenderTarget, RenderTarget},
    image::TextureFormatPixelInfo,
    log::LogPlugin,
    prelude::*,
    render::{
        RenderPlugin,
        error_handler::{RenderError, RenderErrorHandler, RenderErrorPolicy},
        gpu_readback::{Readback, ReadbackComplete},
        render_resource::{TextureFormat, TextureUsages},
        settings::{Backends, WgpuSettings},
    },
    window::{ExitCondition, WindowRef},
    winit::WinitPlugin,
};
use std::sync::{Arc, Mutex, OnceLock};

/// Every warning and error logged in this process since the last [`take_warnings`]
/// (target and message), recorded by the log layer the first harness app installs.
static WARNINGS: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// The warnings and errors logged since the last call (`target: message`), in order.
/// Recorded once the first [`HeadlessRender::app`] has installed Bevy's logger.
pub fn take_warnings() -> Vec<String> {
    std::mem::take(&mut *WARNINGS.lock().unwrap_or_else(|e| e.into_inner()))
}

/// The log layer behind [`take_warnings`].
struct WarningRecorder;

impl<S: bevy::log::tracing::Subscriber> bevy::log::tracing_subscriber::Layer<S>
    for WarningRecorder
{
    fn on_event(
        &self,
        event: &bevy::log::tracing::Event<'_>,
        _: bevy::log::tracing_subscriber::layer::Context<'_, S>,
    ) {
        if *event.metadata().level() > bevy::log::Level::WARN {
            return; // info and below
        }
        struct Message(String);
        impl bevy::log::tracing::field::Visit for Message {
            fn record_debug(
                &mut self,
                field: &bevy::log::tracing::field::Field,
                value: &dyn std::fmt::Debug,
            ) {
                if field.name() == "message" {
                    self.0 = format!("{value:?}");
                }
            }
        }
        let mut message = Message(String::new());
        event.record(&mut message);
        WARNINGS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(format!("{}: {}", event.metadata().target(), message.0));
    }
}

/// Pixel format of the capture target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum CaptureFormat {
    /// `Rgba8UnormSrgb`: what a window shows. Linear colour is sRGB-encoded by the GPU.
    #[default]
    Srgb8,
    /// `Rgba16Float`: linear values. Only meaningful for cameras with `Hdr` (otherwise
    /// Bevy renders through an 8-bit sRGB intermediate and the values are quantized).
    LinearF16,
}

impl CaptureFormat {
    fn texture_format(self) -> TextureFormat {
        match self {
            CaptureFormat::Srgb8 => TextureFormat::Rgba8UnormSrgb,
            CaptureFormat::LinearF16 => TextureFormat::Rgba16Float,
        }
    }
}

/// What can go wrong in a headless render.
#[derive(Debug)]
pub enum HarnessError {
    /// No Vulkan adapter (see [`crate::gpu_or_skip`]).
    NoAdapter,
    /// The readback never completed within the frame budget.
    ReadbackTimeout {
        /// Frames waited after requesting the readback.
        frames: u32,
    },
    /// The warm-up condition did not hold within this many updates.
    WarmUpTimeout {
        /// Updates run.
        frames: u32,
    },
    /// The readback returned fewer bytes than the image needs.
    ShortReadback {
        /// Bytes expected (with row padding).
        expected: usize,
        /// Bytes received.
        got: usize,
    },
    /// wgpu reported errors (validation, out of memory, device lost) while rendering:
    /// rendering stopped at the first.
    Render(Vec<String>),
}

impl std::fmt::Display for HarnessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HarnessError::NoAdapter => write!(
                f,
                "no Vulkan adapter (install Debian package `mesa-vulkan-drivers`)"
            ),
            HarnessError::ReadbackTimeout { frames } => {
                write!(f, "GPU readback did not complete within {frames} frames")
            }
            HarnessError::WarmUpTimeout { frames } => {
                write!(f, "the scene was not ready after {frames} warm-up updates")
            }
            HarnessError::ShortReadback { expected, got } => {
                write!(f, "GPU readback returned {got} bytes, expected {expected}")
            }
            HarnessError::Render(errors) => {
                write!(
                    f,
                    "wgpu reported {} error(s): {}",
                    errors.len(),
                    errors.join("; ")
                )
            }
        }
    }
}

impl std::error::Error for HarnessError {}

/// A render read back from the GPU, tightly packed rows from the top-left pixel.
#[derive(Clone, Debug)]
pub struct Capture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Format of `bytes`.
    pub format: CaptureFormat,
    /// Raw texel bytes, `width × height × bytes-per-pixel`, no row padding.
    pub bytes: Vec<u8>,
    /// Wall-clock time of each of the `frames` rendered frames (`App::update`), in
    /// order; the first includes pipeline compilation.
    pub frame_times: Vec<std::time::Duration>,
}

impl Capture {
    /// The capture as 8-bit sRGB RGBA (linear captures are clamped and sRGB-encoded).
    pub fn to_rgba8(&self) -> image::RgbaImage {
        let data = match self.format {
            CaptureFormat::Srgb8 => self.bytes.clone(),
            CaptureFormat::LinearF16 => self
                .to_linear()
                .iter()
                .flat_map(|p| {
                    let [r, g, b, a] = *p;
                    let enc = |c: f32| (linear_to_srgb(c) * 255.0 + 0.5) as u8;
                    [
                        enc(r),
                        enc(g),
                        enc(b),
                        (a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
                    ]
                })
                .collect(),
        };
        image::RgbaImage::from_raw(self.width, self.height, data)
            .expect("capture size matches its dimensions")
    }

    /// Linear RGBA per pixel (8-bit sRGB captures are decoded).
    pub fn to_linear(&self) -> Vec<[f32; 4]> {
        match self.format {
            CaptureFormat::Srgb8 => self
                .bytes
                .chunks_exact(4)
                .map(|p| {
                    let d = |c: u8| srgb_to_linear(c as f32 / 255.0);
                    [d(p[0]), d(p[1]), d(p[2]), p[3] as f32 / 255.0]
                })
                .collect(),
            CaptureFormat::LinearF16 => self
                .bytes
                .chunks_exact(8)
                .map(|p| {
                    std::array::from_fn(|i| {
                        f16_to_f32(u16::from_le_bytes([p[2 * i], p[2 * i + 1]]))
                    })
                })
                .collect(),
        }
    }
}

/// Display (sRGB) value of linear `c`, clamped to [0, 1].
pub(crate) fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear value of display (sRGB) `c` in [0, 1].
pub(crate) fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// IEEE 754 binary16 → f32 (exact; handles subnormals, Inf and NaN).
fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let frac = (h & 0x3ff) as f32;
    match exp {
        0 => sign * frac * (-24f32).exp2(),
        31 if frac == 0.0 => sign * f32::INFINITY,
        31 => f32::NAN,
        _ => sign * (1.0 + frac / 1024.0) * ((exp - 15) as f32).exp2(),
    }
}

/// The capture target of a harness app; cameras aimed at the primary window are
/// retargeted to it.
#[derive(Resource, Clone, Debug)]
pub struct HarnessTarget(pub Handle<Image>);

/// Settings for one headless render.
#[derive(Clone, Debug)]
pub struct HeadlessRender {
    /// Target width in pixels.
    pub width: u32,
    /// Target height in pixels.
    pub height: u32,
    /// Frames to render before the capture (≥ 1). Pipelines compile synchronously, so a
    /// static scene is complete after ~3 frames; animated scenes pick their frame.
    pub frames: u32,
    /// Target format.
    pub format: CaptureFormat,
    /// Render on a separate thread, one frame behind (Bevy's default). Off: the render
    /// world stays a sub-app of the main app, where tests can inspect it.
    pub pipelined: bool,
    /// Updates run until this holds before the `frames` counted ones (e.g. background
    /// work such as SDF bakes finished), so captures do not depend on machine speed.
    pub warm_up: Option<fn(&mut World) -> bool>,
    /// The asset folder (`AssetPlugin::file_path`); `None`: Bevy's default, `assets`.
    pub asset_root: Option<std::path::PathBuf>,
}

/// One Bevy app at a time per process — rendering or being torn down: lavapipe has 2
/// cores to share, and a global logger can only be installed once. Building apps is not
/// covered: apps built, run and dropped concurrently in one process crashed lavapipe
/// (SIGSEGV / `free(): invalid pointer`, 1 run in 4 of `tests/df_shadows.rs`), so
/// `cargo xtask test` runs one test at a time per binary (`RUST_TEST_THREADS=1`).
static RENDER_LOCK: Mutex<()> = Mutex::new(());

/// The wgpu errors of the app rendering now (the render lock's holder): the harness's
/// [`RenderErrorHandler`] records them and stops rendering, and a run returns
/// [`HarnessError::Render`] (Bevy's default handler quits the app, which a headless
/// harness would only notice as a read-back timeout).
static RENDER_ERRORS: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Bevy asks again every frame while rendering is stopped: each error is kept once.
fn record_render_error(error: &RenderError, _: &mut World, _: &mut World) -> RenderErrorPolicy {
    let text = format!("{:?}: {}", error.ty, error.description);
    let mut errors = RENDER_ERRORS.lock().unwrap_or_else(|e| e.into_inner());
    if !errors.contains(&text) {
        errors.push(text);
    }
    RenderErrorPolicy::StopRendering
}

/// The wgpu errors recorded since the last call (rendering stops at the first): for
/// tests that drive a kept app themselves ([`HeadlessRender::read_target`]).
pub fn take_render_errors() -> Vec<String> {
    std::mem::take(&mut *RENDER_ERRORS.lock().unwrap_or_else(|e| e.into_inner()))
}

/// An app kept after a headless render ([`HeadlessRender::run_keeping_app`]): use it as an
/// [`App`]; dropping it takes the render lock, so its GPU device is never torn down while
/// another test's app renders.
pub struct KeptApp(Option<App>);

impl std::ops::Deref for KeptApp {
    type Target = App;
    fn deref(&self) -> &App {
        self.0.as_ref().expect("present until dropped")
    }
}

impl std::ops::DerefMut for KeptApp {
    fn deref_mut(&mut self) -> &mut App {
        self.0.as_mut().expect("present until dropped")
    }
}

impl Drop for KeptApp {
    fn drop(&mut self) {
        let _guard = RENDER_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        drop(self.0.take());
    }
}

impl HeadlessRender {
    /// `width × height`, 5 frames, 8-bit sRGB.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            frames: 5,
            format: CaptureFormat::Srgb8,
            pipelined: true,
            warm_up: None,
            asset_root: None,
        }
    }

    /// Runs updates until `ready` holds (at most 1,000) before counting frames.
    pub fn warm_up(mut self, ready: fn(&mut World) -> bool) -> Self {
        self.warm_up = Some(ready);
        self
    }

    /// Renders on the main thread so that `app.sub_app(RenderApp)` stays reachable.
    pub fn without_pipelining(mut self) -> Self {
        self.pipelined = false;
        self
    }

    /// Sets the number of frames rendered before the capture.
    pub fn frames(mut self, frames: u32) -> Self {
        self.frames = frames.max(1);
        self
    }

    /// Sets the capture format.
    pub fn format(mut self, format: CaptureFormat) -> Self {
        self.format = format;
        self
    }

    /// A windowless app with Bevy's default plugins on the Vulkan backend, synchronous
    /// pipeline compilation (deterministic first frames), and the [`HarnessTarget`]
    /// image. Add the scene to it, then call [`HeadlessRender::run`].
    pub fn app(&self) -> App {
        static LOGGER: OnceLock<()> = OnceLock::new();
        let first_logger = LOGGER.set(()).is_ok();
        let mut app = App::new();
        let plugins = DefaultPlugins
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .set(RenderPlugin {
                render_creation: WgpuSettings {
                    backends: Some(Backends::VULKAN),
                    ..default()
                }
                .into(),
                synchronous_pipeline_compilation: true,
                ..default()
            })
            .set(LogPlugin {
                // lavapipe is a software adapter (Bevy warning B0006): expected here.
                // The last in-flight readback may land after the app is dropped: harmless.
                filter: "wgpu=error,naga=warn,bevy_render::renderer=error,\
                         bevy_render::gpu_readback=error"
                    .into(),
                level: bevy::log::Level::WARN,
                custom_layer: |_| Some(Box::new(WarningRecorder)),
                ..default()
            })
            .set(AssetPlugin {
                file_path: self.asset_root.as_ref().map_or_else(
                    || AssetPlugin::default().file_path,
                    |p| p.to_string_lossy().into_owned(),
                ),
                ..default()
            })
            .disable::<WinitPlugin>();
        let plugins = if self.pipelined {
            plugins
        } else {
            plugins.disable::<bevy::render::pipelined_rendering::PipelinedRenderingPlugin>()
        };
        if first_logger {
            app.add_plugins(plugins);
        } else {
            app.add_plugins(plugins.disable::<LogPlugin>());
        }

        let mut target =
            Image::new_target_texture(self.width, self.height, self.format.texture_format(), None);
        target.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let handle = app.world_mut().resource_mut::<Assets<Image>>().add(target);
        app.insert_resource(HarnessTarget(handle))
            .insert_resource(RenderErrorHandler(record_render_error))
            .add_systems(PostStartup, retarget_window_cameras)
            .add_systems(PreUpdate, retarget_window_cameras);
        app
    }

    /// Renders `frames` frames of `app` (built with [`HeadlessRender::app`]) and reads
    /// the target back.
    pub fn run(&self, app: App) -> Result<Capture, HarnessError> {
        self.run_keeping_app(app).map(|(capture, _)| capture)
    }

    /// [`HeadlessRender::run`], also returning the app so that tests can inspect the
    /// main world after rendering (it is torn down under the render lock when dropped).
    pub fn run_keeping_app(&self, app: App) -> Result<(Capture, KeptApp), HarnessError> {
        if crate::vulkan_adapter().is_none() {
            return Err(HarnessError::NoAdapter);
        }
        // Declared before the guard: on an early return the guard is released first and
        // the app's drop takes the lock again.
        let mut app = KeptApp(Some(app));
        let _guard = RENDER_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        take_render_errors();
        app.finish();
        app.cleanup();
        if let Some(ready) = self.warm_up {
            const MAX_WARM_UP: u32 = 1_000;
            let mut n = 0;
            while !ready(app.world_mut()) {
                if n == MAX_WARM_UP {
                    let errors = take_render_errors();
                    if !errors.is_empty() {
                        return Err(HarnessError::Render(errors));
                    }
                    return Err(HarnessError::WarmUpTimeout { frames: n });
                }
                app.update();
                n += 1;
            }
        }
        let frame_times = (0..self.frames)
            .map(|_| {
                let start = std::time::Instant::now();
                app.update();
                start.elapsed()
            })
            .collect();

        let capture = self.read_target(&mut app);
        let errors = take_render_errors();
        if !errors.is_empty() {
            return Err(HarnessError::Render(errors));
        }
        let mut capture = capture?;
        capture.frame_times = frame_times;
        Ok((capture, app))
    }

    /// Reads the [`HarnessTarget`] of a running harness app back (updating it until the
    /// read-back arrives, at most 30 frames).
    pub fn read_target(&self, app: &mut App) -> Result<Capture, HarnessError> {
        let handle = app.world().resource::<HarnessTarget>().0.clone();
        let slot: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
        let sink = slot.clone();
        let reader = app
            .world_mut()
            .spawn(Readback::texture(handle))
            .observe(move |event: On<ReadbackComplete>| {
                sink.lock()
                    .unwrap()
                    .get_or_insert_with(|| event.data.clone());
            })
            .id();
        const MAX_WAIT_FRAMES: u32 = 30;
        for _ in 0..MAX_WAIT_FRAMES {
            app.update();
            if slot.lock().unwrap().is_some() {
                break;
            }
        }
        app.world_mut().despawn(reader);
        let data = slot
            .lock()
            .unwrap()
            .take()
            .ok_or(HarnessError::ReadbackTimeout {
                frames: MAX_WAIT_FRAMES,
            })?;
        self.unpad(data)
    }

    /// Removes wgpu's 256-byte row alignment from a texture readback.
    fn unpad(&self, data: Vec<u8>) -> Result<Capture, HarnessError> {
        let pixel = self
            .format
            .texture_format()
            .pixel_size()
            .expect("uncompressed format");
        let row = self.width as usize * pixel;
        let padded = row.div_ceil(256) * 256;
        let expected = padded * self.height as usize;
        if data.len() < expected {
            return Err(HarnessError::ShortReadback {
                expected,
                got: data.len(),
            });
        }
        let bytes = data
            .chunks_exact(padded)
            .take(self.height as usize)
            .flat_map(|r| &r[..row])
            .copied()
            .collect();
        Ok(Capture {
            width: self.width,
            height: self.height,
            format: self.format,
            bytes,
            frame_times: Vec::new(),
        })
    }
}

/// Points every camera that targets the primary window (there is none) at the capture
/// image, so scene code is the same for windowed and headless runs.
fn retarget_window_cameras(
    target: Res<HarnessTarget>,
    mut cameras: Query<&mut RenderTarget, Added<Camera>>,
) {
    for mut camera_target in &mut cameras {
        if matches!(*camera_target, RenderTarget::Window(WindowRef::Primary)) {
            *camera_target = RenderTarget::Image(ImageRenderTarget::from(target.0.clone()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f16_decoding_is_exact() {
        let cases = [
            (0x0000, 0.0),
            (0x3c00, 1.0),
            (0xc000, -2.0),
            (0x3555, 0.333_251_95),
            (0x0001, 5.960_464_5e-8),
            (0x7bff, 65504.0),
        ];
        for (bits, value) in cases {
            assert_eq!(f16_to_f32(bits), value, "{bits:#06x}");
        }
        assert!(f16_to_f32(0x7c00).is_infinite());
        assert!(f16_to_f32(0x7e00).is_nan());
    }

    #[test]
    fn unpad_strips_row_alignment() {
        let r = HeadlessRender::new(3, 2);
        let mut data = vec![0u8; 512];
        data[..12].copy_from_slice(&[1; 12]);
        data[256..268].copy_from_slice(&[2; 12]);
        let c = r.unpad(data).unwrap();
        assert_eq!(c.bytes.len(), 24);
        assert!(c.bytes[..12].iter().all(|&b| b == 1) && c.bytes[12..].iter().all(|&b| b == 2));
        assert!(matches!(
            r.unpad(vec![0; 300]),
            Err(HarnessError::ShortReadback { .. })
        ));
    }
}
