//! Penumbra's WGSL shader sources, embedded at compile time from this crate's `shaders/`
//! folder (the workspace's top-level `shaders/` links to it), with the `naga_oil` import
//! path each one declares.
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
            source: include_str!(concat!("../shaders/", $path)),
        }),*];
    };
}

shader_files! {
    "common/math.wgsl" => Some("penumbra::math"),
    "common/scan.wgsl" => Some("penumbra::common::scan"),
    "dof/types.wgsl" => Some("penumbra::dof::types"),
    "dof/sprites.wgsl" => Some("penumbra::dof::sprites"),
    "dof/scatter.wgsl" => Some("penumbra::dof::scatter"),
    "dof/composite.wgsl" => Some("penumbra::dof::composite"),
    "dof/compact.wgsl" => Some("penumbra::dof::compact"),
    "sss/profile.wgsl" => Some("penumbra::sss::profile"),
    "sss/scatter.wgsl" => None,
    "tessellation/patch.wgsl" => Some("penumbra::tessellation::patch"),
    "tessellation/layout.wgsl" => Some("penumbra::tessellation::layout"),
    "tessellation/tessellate.wgsl" => Some("penumbra::tessellation::tessellate"),
    "reflections/types.wgsl" => Some("penumbra::reflections::types"),
    "reflections/common.wgsl" => Some("penumbra::reflections::common"),
    "reflections/spheres.wgsl" => None,
    "reflections/trace.wgsl" => None,
    "reflections/cull.wgsl" => None,
    "hair/samples.wgsl" => Some("penumbra::hair::samples"),
    "hair/common.wgsl" => Some("penumbra::hair::common"),
    "hair/draw.wgsl" => None,
    "hair/prepass.wgsl" => None,
    "hair/shadows.wgsl" => Some("penumbra::hair::shadows"),
    "hair/df_visibility.wgsl" => Some("penumbra::hair::df_visibility"),
    "df/object.wgsl" => Some("penumbra::df::object"),
    "df/apply_deltas.wgsl" => Some("penumbra::df::apply_deltas"),
    "df/cull.wgsl" => Some("penumbra::df::cull"),
    "df/distance.wgsl" => Some("penumbra::df::distance"),
    "df/debug_view.wgsl" => Some("penumbra::df::debug_view"),
    "df/shadow.wgsl" => Some("penumbra::df::shadow"),
    "df/shadow_cull.wgsl" => Some("penumbra::df::shadow_cull"),
    "df/shadow_trace.wgsl" => Some("penumbra::df::shadow_trace"),
    "df/shadow_upsample.wgsl" => Some("penumbra::df::shadow_upsample"),
    "df/shadow_grid.wgsl" => Some("penumbra::df::shadow_grid"),
    "df/shadow_grid_build.wgsl" => Some("penumbra::df::shadow_grid_build"),
    "df/ao.wgsl" => Some("penumbra::df::ao"),
    "df/ao_trace.wgsl" => Some("penumbra::df::ao_trace"),
    "df/ao_upsample.wgsl" => Some("penumbra::df::ao_upsample"),
    "df/ao_temporal.wgsl" => Some("penumbra::df::ao_temporal"),
    "df/global_compose.wgsl" => Some("penumbra::df::global_compose"),
    "df/global_field.wgsl" => Some("penumbra::df::global_field"),
    "df/heightfield.wgsl" => Some("penumbra::df::heightfield"),
    "df/particles.wgsl" => Some("penumbra::df::particles"),
    "df/rebake.wgsl" => Some("penumbra::df::rebake"),
    "df/particles_draw.wgsl" => None,
    "df/face_normal.wgsl" => None,
    "df/global_field_debug.wgsl" => Some("penumbra::df::global_field_debug"),
    "lighting/masks.wgsl" => Some("penumbra::lighting::masks"),
    "lighting/lights.wgsl" => Some("penumbra::lighting::lights"),
    "lighting/ao.wgsl" => Some("penumbra::lighting::ao"),
    "lighting/msaa.wgsl" => Some("penumbra::lighting::msaa"),
    "lighting/msaa_view.wgsl" => Some("penumbra::lighting::msaa_view"),
    "lighting/msaa_classify.wgsl" => None,
    "lighting/pass.wgsl" => None,
    "lighting/buffer_dump.wgsl" => Some("penumbra::lighting::buffer_dump"),
}

impl ShaderFile {
    /// Whether the file imports Bevy's shader modules (`bevy_pbr::…`), directly or
    /// through a Penumbra module that does: those compose only inside Bevy, with its
    /// shader definitions, so they are checked by the renderer tests on lavapipe rather
    /// than by this crate's composition test.
    pub fn imports_bevy(&self) -> bool {
        self.source.lines().any(|l| {
            let l = l.trim_start();
            l.starts_with("#import bevy_")
                || l.strip_prefix("#import ").is_some_and(|path| {
                    SHADERS.iter().any(|f| {
                        f.path != self.path
                            && f.import_path.is_some_and(|p| path.starts_with(p))
                            && f.imports_bevy()
                    })
                })
        })
    }
}

/// Absolute path of this crate's `shaders/` folder at build time (for tests and tools).
pub fn shaders_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders")
}

/// The `#define_import_path` declared in a WGSL source, if any.
pub fn declared_import_path(source: &str) -> Option<&str> {
    source.lines().find_map(|line| {
        line.trim()
            .strip_prefix("#define_import_path")
            .map(str::trim)
    })
}

/// The library file declaring `import_path`.
pub fn by_import_path(import_path: &str) -> Option<&'static ShaderFile> {
    SHADERS.iter().find(|f| f.import_path == Some(import_path))
}

/// Why [`flatten`] failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FlattenError(pub String);

impl std::fmt::Display for FlattenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for FlattenError {}

/// `source` with every `#import penumbra::…` replaced by the imported module's text
/// (recursively, each module once) and `#define_import_path` lines dropped: plain WGSL
/// for tools that do not speak `naga_oil`, such as contract tests that drive wgpu
/// directly. Penumbra's modules are written so that this textual inclusion and
/// `naga_oil` composition mean the same thing (imported items are used by their bare
/// names, and no two modules define the same name).
/// No shader definition is set: every `#ifdef` block takes its `#else` branch.
pub fn flatten(source: &str) -> Result<String, FlattenError> {
    flatten_with_defs(source, &[])
}

/// [`flatten`] with the shader definitions `defs` set (`#ifdef`, `#ifndef`, `#else`
/// and `#endif` are resolved as `naga_oil` does for boolean definitions).
pub fn flatten_with_defs(source: &str, defs: &[&str]) -> Result<String, FlattenError> {
    let mut out = String::new();
    let mut included = Vec::new();
    flatten_into(source, defs, &mut out, &mut included)?;
    Ok(out)
}

/// Whether the lines under the open conditionals are kept.
fn conditions_hold(stack: &[bool]) -> bool {
    stack.iter().all(|&keep| keep)
}

fn flatten_into(
    source: &str,
    defs: &[&str],
    out: &mut String,
    included: &mut Vec<&'static str>,
) -> Result<(), FlattenError> {
    let mut lines = source.lines();
    // One entry per open `#ifdef` / `#ifndef`: whether its current branch is kept.
    let mut stack: Vec<bool> = Vec::new();
    while let Some(line) = lines.next() {
        let trimmed = line.trim();
        if let Some(name) = trimmed.strip_prefix("#ifdef ") {
            stack.push(defs.contains(&name.trim()));
            continue;
        }
        if let Some(name) = trimmed.strip_prefix("#ifndef ") {
            stack.push(!defs.contains(&name.trim()));
            continue;
        }
        if trimmed == "#else" {
            let top = stack
                .last_mut()
                .ok_or_else(|| FlattenError("#else without #ifdef".into()))?;
            *top = !*top;
            continue;
        }
        if trimmed == "#endif" {
            stack
                .pop()
                .ok_or_else(|| FlattenError("#endif without #ifdef".into()))?;
            continue;
        }
        if !conditions_hold(&stack) || trimmed.starts_with("#define_import_path") {
            continue;
        }
        let Some(rest) = trimmed.strip_prefix("#import") else {
            out.push_str(line);
            out.push('\n');
            continue;
        };
        // `#import path` or `#import path::{items}`, the list possibly spanning lines.
        let mut statement = rest.trim().to_string();
        if statement.contains('{') {
            while !statement.contains('}') {
                let next = lines
                    .next()
                    .ok_or_else(|| FlattenError(format!("unterminated import: {line}")))?;
                statement.push_str(next.trim());
            }
        }
        let path = statement
            .split("::{")
            .next()
            .unwrap_or_default()
            .trim()
            .trim_end_matches(';');
        // `#import a::b::item` imports `item` from module `a::b`.
        let mut module = path;
        let file = loop {
            if let Some(file) = by_import_path(module) {
                break file;
            }
            match module.rsplit_once("::") {
                Some((parent, _)) => module = parent,
                None => return Err(FlattenError(format!("unknown import {path:?}"))),
            }
        };
        if !included.contains(&file.path) {
            included.push(file.path);
            flatten_into(file.source, defs, out, included)?;
        }
    }
    if !stack.is_empty() {
        return Err(FlattenError("#ifdef without #endif".into()));
    }
    Ok(())
}
