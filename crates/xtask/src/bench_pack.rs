//! `cargo xtask bench-pack`: the GPU benchmark (`examples/penumbra_bench.rs`) built,
//! stripped and packed with the scenes it reads into one gzip-compressed tar archive,
//! for a Linux machine that has a Vulkan driver and nothing else (no Rust, no network).
//!
//! The archive (`target/bench-pack/penumbra-bench.tar.gz`, at most [`MAX_ARCHIVE_BYTES`])
//! unpacks to `penumbra-bench/`: the binary, `scenes/` (from `../shared/scenes`:
//! `CornellBox.glb`, `DepthOfFieldExample.glb`, `FlightHelmet/`, `Fox.glb`), `run.sh` (runs the
//! binary from any folder, passing its arguments; `bench_run.sh`), `plan.sh` (a lent
//! GPU's short session in one command, the open questions first; `bench_plan.sh`),
//! `lib/libvulkan.so.1`
//! (the build machine's Vulkan loader, used only where the GPU machine has none) and
//! `README.txt`. The dev profile is
//! used, as the tests': dependencies at opt-level 1 (Bevy's CPU side), the GPU's work
//! unchanged; a release build would add a cold ~30 minute build of its own.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The archive's limit: 60 MiB (a GPU machine takes at most 64 MiB with the tree).
pub const MAX_ARCHIVE_BYTES: u64 = 60 << 20;

/// The glTF files and folders the benchmark reads, under `../shared/scenes`.
const SCENES: &[&str] = &[
    "CornellBox.glb",
    "DepthOfFieldExample.glb",
    "FlightHelmet",
    "Fox.glb",
];

/// Builds, strips and packs; prints the command that runs it elsewhere.
pub fn bench_pack(cargo: &std::ffi::OsStr, args: &[String]) -> Result<(), String> {
    if let Some(a) = args.first() {
        return Err(format!("bench-pack takes no arguments (got `{a}`)"));
    }
    let root = crate::workspace_root()?;
    let scenes = root.join("../shared/scenes");
    if !scenes.is_dir() {
        return Err(format!(
            "the benchmark's scenes are read from {} (not found)",
            scenes.display()
        ));
    }
    // `--workspace`: the features of the whole workspace, as `cargo xtask test` builds
    // them (the example alone would select other features of Bevy's dependencies and
    // rebuild Bevy: a second cold build).
    run(Command::new(cargo).current_dir(&root).args([
        "build",
        "--workspace",
        "--example",
        "penumbra-bench",
    ]))?;
    let target = target_dir(cargo, &root)?;
    let binary = target.join("debug/examples/penumbra-bench");
    let pack = target.join("bench-pack");
    let stage = pack.join("penumbra-bench");
    let _ = std::fs::remove_dir_all(&stage);
    std::fs::create_dir_all(stage.join("scenes")).map_err(|e| format!("{e}"))?;
    let staged_binary = stage.join("penumbra-bench");
    std::fs::copy(&binary, &staged_binary).map_err(|e| format!("{}: {e}", binary.display()))?;
    run(Command::new("strip").arg(&staged_binary))?;
    for scene in SCENES {
        run(Command::new("cp")
            .arg("-r")
            .arg(scenes.join(scene))
            .arg(stage.join("scenes")))?;
    }
    write_script(&stage)?;
    let archive = pack.join("penumbra-bench.tar.gz");
    run(Command::new("tar")
        .arg("-C")
        .arg(&pack)
        .arg("-czf")
        .arg(&archive)
        .arg("penumbra-bench"))?;
    let bytes = std::fs::metadata(&archive)
        .map_err(|e| format!("{}: {e}", archive.display()))?
        .len();
    let binary_bytes = std::fs::metadata(&staged_binary).map_or(0, |m| m.len());
    println!(
        "bench-pack: {} — {:.1} MiB (limit {} MiB; stripped binary {:.1} MiB; needs glibc {} or newer)",
        archive.display(),
        bytes as f64 / 1048576.0,
        MAX_ARCHIVE_BYTES >> 20,
        binary_bytes as f64 / 1048576.0,
        glibc_needed(&staged_binary).unwrap_or_else(|| "(unknown)".into())
    );
    if bytes > MAX_ARCHIVE_BYTES {
        return Err(format!(
            "the archive is {bytes} bytes, over the {MAX_ARCHIVE_BYTES}-byte limit"
        ));
    }
    println!("bench-pack: on a Linux machine with a Vulkan driver, from the archive's folder:");
    println!(
        "  tar -xzf penumbra-bench.tar.gz && penumbra-bench/run.sh --sizes 1080p,4k --frames 120 --out bench-out"
    );
    println!(
        "bench-pack: a short GPU session, the open questions first: penumbra-bench/plan.sh bench-out"
    );
    Ok(())
}

/// The target folder cargo builds into (`CARGO_TARGET_DIR` or the workspace's).
pub(crate) fn target_dir(cargo: &std::ffi::OsStr, root: &Path) -> Result<PathBuf, String> {
    let out = Command::new(cargo)
        .current_dir(root)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .output()
        .map_err(|e| format!("cargo metadata: {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let key = "\"target_directory\":\"";
    let start = text
        .find(key)
        .ok_or("cargo metadata: no target_directory")?
        + key.len();
    let end = text[start..].find('"').ok_or("cargo metadata: bad JSON")? + start;
    Ok(PathBuf::from(&text[start..end]))
}

/// The newest glibc symbol version the binary needs (from `objdump -T`), if known.
fn glibc_needed(binary: &Path) -> Option<String> {
    let out = Command::new("objdump")
        .arg("-T")
        .arg(binary)
        .output()
        .ok()?;
    String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .filter_map(|w| w.trim_start_matches('(').strip_prefix("GLIBC_"))
        .map(|v| v.trim_end_matches(')').to_owned())
        .max_by_key(|v| {
            v.split('.')
                .map(|p| p.parse::<u32>().unwrap_or(0))
                .collect::<Vec<_>>()
        })
}

/// `run.sh`: the Vulkan loader and NVIDIA's headless driver found (see its comments).
const RUN_SH: &str = include_str!("bench_run.sh");

/// `plan.sh`: a lent GPU's short session in one command (see its comments).
const PLAN_SH: &str = include_str!("bench_plan.sh");

/// The Vulkan loader packed for machines without one (a GPU container may carry the
/// driver but not the loader), copied from the build machine.
const VULKAN_LOADERS: &[&str] = &[
    "/usr/lib/x86_64-linux-gnu/libvulkan.so.1",
    "/lib/x86_64-linux-gnu/libvulkan.so.1",
    "/usr/lib64/libvulkan.so.1",
];

fn write_script(stage: &Path) -> Result<(), String> {
    let script = stage.join("run.sh");
    std::fs::write(&script, RUN_SH).map_err(|e| format!("{}: {e}", script.display()))?;
    match VULKAN_LOADERS.iter().map(Path::new).find(|p| p.is_file()) {
        Some(loader) => {
            std::fs::create_dir_all(stage.join("lib")).map_err(|e| format!("{e}"))?;
            // `copy` follows the symbolic link: the library itself.
            std::fs::copy(loader, stage.join("lib/libvulkan.so.1"))
                .map_err(|e| format!("{}: {e}", loader.display()))?;
        }
        None => eprintln!(
            "bench-pack: no libvulkan.so.1 here to pack: the archive needs one on the GPU machine"
        ),
    }
    let plan = stage.join("plan.sh");
    std::fs::write(&plan, PLAN_SH).map_err(|e| format!("{}: {e}", plan.display()))?;
    run(Command::new("chmod").arg("+x").arg(&script).arg(&plan))?;
    std::fs::write(
        stage.join("README.txt"),
        "Penumbra's GPU benchmark, packed by `cargo xtask bench-pack`.\n\n\
         Run: ./run.sh --sizes 1080p,4k --frames 120 --out bench-out\n\
         Options: ./run.sh --help\n\
         A short GPU session (the open questions first, one process per scene):\n\
         ./plan.sh bench-out, then bench-out/all.md\n\
         Writes bench-out/bench.json and bench-out/bench.md (also printed).\n\
         Needs: Linux and a GPU's Vulkan driver (its ICD); the Vulkan loader is packed\n\
         in lib/ for machines without one, and NVIDIA's driver is reached through its EGL\n\
         library when there is no display (see run.sh).\n",
    )
    .map_err(|e| format!("README.txt: {e}"))
}

pub(crate) fn run(command: &mut Command) -> Result<(), String> {
    let status = command
        .status()
        .map_err(|e| format!("{:?}: {e}", command.get_program()))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{command:?} failed ({status})"))
    }
}
