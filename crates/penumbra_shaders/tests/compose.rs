//! Every `.wgsl` file under `shaders/` composes with `naga_oil` (as Bevy composes shaders)
//! and the composed module passes naga's validator. No GPU needed.

use naga::valid::{Capabilities, ValidationFlags, Validator};
use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, ComposerError, ComposerErrorInner, NagaModuleDescriptor,
    ShaderDefValue, ShaderLanguage, ShaderType,
};
use penumbra_shaders::{SHADERS, ShaderFile, declared_import_path, shaders_dir};
use std::path::Path;

fn wgsl_files_on_disk(dir: &Path, out: &mut Vec<String>) {
    for entry in std::fs::read_dir(dir).expect("read shaders/") {
        let path = entry.expect("dir entry").path();
        if path.is_dir() {
            wgsl_files_on_disk(&path, out);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            let rel = path.strip_prefix(shaders_dir()).expect("under shaders/");
            out.push(rel.to_string_lossy().replace('\\', "/"));
        }
    }
}

/// Adds every importable module to a composer, dependencies first (`naga_oil` needs a
/// module's imports to be present when it is added).
fn composer_with_library(files: &[ShaderFile]) -> Result<Composer, String> {
    let mut composer = Composer::default().with_capabilities(Capabilities::all());
    let mut pending: Vec<&ShaderFile> = files.iter().filter(|f| f.import_path.is_some()).collect();
    while !pending.is_empty() {
        let before = pending.len();
        let (mut missing_imports, mut errors) = (Vec::new(), Vec::new());
        pending.retain(|f| {
            let desc = ComposableModuleDescriptor {
                source: f.source,
                file_path: f.path,
                language: ShaderLanguage::Wgsl,
                ..Default::default()
            };
            match composer.add_composable_module(desc) {
                Ok(_) => false,
                Err(e) if matches!(e.inner, ComposerErrorInner::ImportNotFound(..)) => {
                    missing_imports.push(describe(&composer, &e));
                    true // retry once its imports are in
                }
                Err(e) => {
                    errors.push(describe(&composer, &e));
                    false
                }
            }
        });
        if !errors.is_empty() {
            return Err(errors.join("\n"));
        }
        if pending.len() == before {
            return Err(missing_imports.join("\n"));
        }
    }
    Ok(composer)
}

fn describe(composer: &Composer, e: &ComposerError) -> String {
    e.emit_to_string(composer)
}

/// Composes one file into a full naga module and validates it.
fn compose_and_validate(composer: &mut Composer, file: &ShaderFile) -> Result<(), String> {
    compose_with_defs(composer, file, &[])
}

/// [`compose_and_validate`] with boolean shader definitions set.
fn compose_with_defs(
    composer: &mut Composer,
    file: &ShaderFile,
    defs: &[&str],
) -> Result<(), String> {
    let module = composer
        .make_naga_module(NagaModuleDescriptor {
            source: file.source,
            file_path: file.path,
            shader_type: ShaderType::Wgsl,
            shader_defs: defs
                .iter()
                .map(|d| (d.to_string(), ShaderDefValue::Bool(true)))
                .collect(),
            ..Default::default()
        })
        .map_err(|e| describe(composer, &e))?;
    Validator::new(ValidationFlags::all(), Capabilities::all())
        .validate(&module)
        .map_err(|e| format!("{}: naga validation: {e:?}", file.path))?;
    Ok(())
}

#[test]
fn every_wgsl_file_is_embedded_with_its_import_path() {
    let mut on_disk = Vec::new();
    wgsl_files_on_disk(&shaders_dir(), &mut on_disk);
    on_disk.sort();
    let mut embedded: Vec<String> = SHADERS.iter().map(|s| s.path.to_string()).collect();
    embedded.sort();
    assert_eq!(
        on_disk, embedded,
        "penumbra_shaders::SHADERS must list every .wgsl under shaders/"
    );
    for s in SHADERS {
        assert_eq!(
            declared_import_path(s.source),
            s.import_path,
            "{}: #define_import_path",
            s.path
        );
        assert!(
            s.import_path.is_none_or(|p| p.starts_with("penumbra::")),
            "{}: import paths live under penumbra::",
            s.path
        );
    }
}

fn standalone() -> Vec<ShaderFile> {
    SHADERS
        .iter()
        .filter(|f| !f.imports_bevy())
        .copied()
        .collect()
}

#[test]
fn every_shader_composes_and_validates() {
    // Files importing Bevy's modules compose only inside Bevy (its shader defs): the
    // lighting-pass tests on lavapipe build them.
    let standalone = standalone();
    let mut composer = composer_with_library(&standalone).unwrap_or_else(|e| panic!("{e}"));
    let failures: Vec<String> = standalone
        .iter()
        .filter_map(|f| compose_and_validate(&mut composer, f).err())
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The variants Penumbra compiles with shader definitions (deferred MSAA's per-sample
/// shadow trace and AO upsample, the bokeh passes' multisampled depth) compose and validate too, and flatten (for contract
/// tests) to the same branch.
#[test]
fn shader_def_variants_compose_and_validate() {
    let standalone = standalone();
    let mut composer = composer_with_library(&standalone).unwrap_or_else(|e| panic!("{e}"));
    for (path, def, marker) in [
        (
            "df/shadow_trace.wgsl",
            "PENUMBRA_SAMPLE_TRACE",
            "pixel_class",
        ),
        (
            "df/ao_upsample.wgsl",
            "PENUMBRA_SAMPLE_UPSAMPLE",
            "upsample_samples",
        ),
        (
            "dof/sprites.wgsl",
            "MULTISAMPLED",
            "texture_depth_multisampled_2d",
        ),
        (
            "dof/composite.wgsl",
            "MULTISAMPLED",
            "texture_depth_multisampled_2d",
        ),
    ] {
        let file = standalone.iter().find(|f| f.path == path).expect(path);
        compose_with_defs(&mut composer, file, &[def]).unwrap_or_else(|e| panic!("{e}"));
        let with = penumbra_shaders::flatten_with_defs(file.source, &[def]).expect("flattens");
        let without = penumbra_shaders::flatten(file.source).expect("flattens");
        assert!(with.contains(marker) && !without.contains(marker), "{path}");
    }
    assert!(penumbra_shaders::flatten("#ifdef A\nx\n").is_err());
    assert!(penumbra_shaders::flatten("#else\n").is_err());
}

/// The check can fail: a type error in a module that imports the library is reported.
#[test]
fn broken_shader_is_rejected() {
    let mut composer = composer_with_library(&standalone()).unwrap();
    let good = ShaderFile {
        path: "probe_good.wgsl",
        import_path: None,
        source: "#import penumbra::math::sd_box\n\
                 @compute @workgroup_size(1) fn main() { let d: f32 = sd_box(vec3(1.0), vec3(0.5)); }",
    };
    compose_and_validate(&mut composer, &good).unwrap();
    let wrong_type = ShaderFile {
        source: "#import penumbra::math::sd_box\n\
                 @compute @workgroup_size(1) fn main() { let d: vec2<f32> = sd_box(vec3(1.0), vec3(0.5)); }",
        ..good
    };
    assert!(compose_and_validate(&mut composer, &wrong_type).is_err());
    let missing_import = ShaderFile {
        source: "#import penumbra::does_not_exist::f\n@compute @workgroup_size(1) fn main() { f(); }",
        ..good
    };
    assert!(compose_and_validate(&mut composer, &missing_import).is_err());
}
