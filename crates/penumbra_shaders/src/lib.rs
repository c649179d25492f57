//! Penumbra's WGSL shader sources, embedded at compile time from the workspace's
//! top-level `shaders/` folder, with the `naga_oil` import path each one declares.
//!
//! The Bevy side (`penumbra::PenumbraCorePlugin`) registers every module here as a
//! `Shader` asset so that `#import penumbra::…` resolves in any Penumbra pipeline. This
//! crate has no Bevy dependency so its test — compose every `.wgsl` under `shaders/` with
//! `naga_oil`, as Bevy does, and validate the result with naga — runs in seconds.

/// One WGSL file under `shaders/`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderFile {
    /// Path relative to `shaders/`, with `/` separators (e.g. `common/math.wgsl`).
    pub path: &'static str,
    /// The file's `#define_import_path`, if it is an importable module.
    pub import_path: Option<&'static str>,
    /// WGSL source.
    pub source: &'static str,
}

macro_rules! shader_files {
    ($($path:literal => $import:expr),* $(,)?) => {
        /// Every WGSL file under `shaders/` (a test checks that none is missing).
        pub const SHADERS: &[ShaderFile] = &[$(ShaderFile {
            path: $path,
            import_path: $import,
            source: include_str!(concat!("../../../shaders/", $path)),
        }),*];
    };
}

shader_files! {
    "common/math.wgsl" => Some("penumbra::math"),
}

/// Absolute path of the workspace's `shaders/` folder at build time (for tests and tools).
pub fn shaders_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shaders")
}

/// The `#define_import_path` declared in a WGSL source, if any.
pub fn declared_import_path(source: &str) -> Option<&str> {
    source.lines().find_map(|line| {
        line.trim()
            .strip_prefix("#define_import_path")
            .map(str::trim)
    })
}
