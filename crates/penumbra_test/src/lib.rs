//! Headless render-test harness for Penumbra.
//!
//! Builds a Bevy app with no window, renders it for N frames into an image target on
//! whatever Vulkan adapter exists (Mesa lavapipe on CI), reads the target back and
//! compares it with a reference image under explicit tolerances, writing
//! `actual` / `expected` / `diff` PNGs on failure.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use penumbra_test::{HeadlessRender, gpu_or_skip};
//!
//! if !gpu_or_skip("my_test") { return; }
//! let render = HeadlessRender::new(64, 64);
//! let mut app = render.app();
//! app.add_systems(Startup, |mut commands: Commands| {
//!     // Cameras that target the (absent) primary window are retargeted to the capture image.
//!     commands.spawn(Camera3d::default());
//! });
//! let capture = render.run(app).unwrap();
//! assert_eq!(capture.to_rgba8().dimensions(), (64, 64));
//! ```
//!
//! - [`gpu`]: adapter probing and the CI rule (under `CI=true` a missing adapter fails).
//! - [`harness`]: [`HeadlessRender`], [`Capture`].
//! - [`compare`]: [`Tolerance`], [`compare_rgba8`], [`assert_images_match`].
//! - [`compute`]: [`GpuCompute`], a bare wgpu device for compute-shader contract tests.
//! - [`awkward_images`]: every image format × size class × data length, for property
//!   tests of image readers.
//! - [`multisample`]: a 4× multisampled depth buffer and G-buffer filled sample by sample.

pub use image;
pub use wgpu;

pub mod awkward_images;
pub mod compare;
pub mod compute;
pub mod gpu;
pub mod harness;
pub mod multisample;
pub mod supersample;

pub use compare::{
    Comparison, Tolerance, assert_images_match, assert_not_blank, check_golden, compare_rgba8,
    output_dir,
};
pub use compute::{GpuCompute, storage_bytes, uniform_bytes};
pub use gpu::{gpu_or_skip, mesa_version, vulkan_adapter};
pub use harness::{
    Capture, CaptureFormat, HarnessError, HeadlessRender, KeptApp, take_render_errors,
    take_warnings,
};
