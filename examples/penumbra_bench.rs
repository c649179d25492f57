//! `penumbra-bench`: Penumbra's passes timed on the GPU beside Bevy's own, headless.
//!
//! ```text
//! cargo run --example penumbra-bench -- --help
//! cargo run --example penumbra-bench -- --sizes tiny --frames 3       # what CI runs
//! cargo run --example penumbra-bench -- --sizes 1080p,4k --frames 120 --out bench/
//! cargo xtask bench-pack    # the same binary and its scenes, packed for a GPU machine
//! ```
//!
//! Every scene (`--scenes`: the showcase room, `CornellBox.glb`,
//! `DepthOfFieldExample.glb`, `FlightHelmet`, a stress scene, the flagship `samaritan`
//! scene with every feature on one camera, `--characters` walking Foxes cast by capsules,
//! by re-baked fields, by their bind-pose field or not at all) is rendered in each of its
//! variants (`bevy`, `penumbra-off`, `penumbra`, and Bevy's counterpart of a Penumbra
//! feature: see `bench/scenes.rs`), each in a fresh app, at every `--sizes` size.
//! A run waits for the scene to load and every distance field to bake, renders
//! `--warm-up` frames, then measures `--frames` frames: per pass the GPU time from
//! timestamp queries (Bevy's render diagnostics) with median and p95, the whole frame's
//! GPU time, the CPU frame time, and the GPU memory held by Penumbra (the allocator's
//! report of resources labelled `penumbra…`). Then it compares each Penumbra feature
//! with Bevy's counterpart measured in the same process (`bench/report.rs`) and writes
//! `bench.json` and `bench.md` to `--out` (the table also goes to standard output).
//!
//! Needs a Vulkan driver (a GPU's, or Mesa's lavapipe); nothing else, no network.

// The showcase and the flagship scene each bring the examples' shared command line.
#![allow(clippy::duplicate_mod)]

use bevy::prelude::*;
use bevy::render::diagnostic::RenderDiagnosticsPlugin;
use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

#[path = "bench/characters.rs"]
pub mod characters;
#[path = "bench/measure.rs"]
pub mod measure;
#[path = "bench/report.rs"]
pub mod report;
#[path = "bench/scenes.rs"]
pub mod scenes;

#[allow(dead_code, reason = "only the flagship's scene is used")]
#[path = "samaritan.rs"]
mod samaritan;
#[allow(dead_code, reason = "only the showcase's scene is used")]
#[path = "showcase.rs"]
mod showcase;

use measure::{Memory, Samples, Stats};
use scenes::{Run, SceneKind, Variant};

/// Penumbra's GPU benchmark: every scene in every variant, per-pass GPU times beside
/// Bevy's own passes.
#[derive(Parser, Debug, Clone)]
#[command(name = "penumbra-bench", version)]
pub struct Args {
    /// Scenes to render, comma-separated [default: all].
    #[arg(long, value_enum, value_delimiter = ',')]
    pub scenes: Vec<SceneKind>,
    /// Only these variants (of each scene's own) [default: each scene's all].
    #[arg(long, value_enum, value_delimiter = ',')]
    pub variants: Vec<Variant>,
    /// Render sizes, comma-separated: `1080p` (1920x1080), `4k` (3840x2160), `tiny`
    /// (160x90, for CI) or `WxH`.
    #[arg(long, value_delimiter = ',', default_value = "1080p,4k", value_parser = parse_size)]
    pub sizes: Vec<UVec2>,
    /// Frames measured per run, after the warm-up (at least 60 for figures to publish).
    #[arg(long, default_value_t = 60)]
    pub frames: u32,
    /// Frames rendered and not measured once the scene is ready (bakes done).
    #[arg(long, default_value_t = 10)]
    pub warm_up: u32,
    /// The folder holding the glTF scenes [default: `scenes/` beside the executable,
    /// else `../shared/scenes` beside the checkout].
    #[arg(long)]
    pub scenes_dir: Option<PathBuf>,
    /// Where `bench.json` and `bench.md` go.
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
    /// A label for the machine in the report (e.g. "RTX 4090, driver 560") [default:
    /// the Vulkan adapter's name and driver].
    #[arg(long)]
    pub device: Option<String>,
    /// Also save each run's last frame as `<scene>-<variant>-<W>x<H>.png` in `--out`.
    #[arg(long)]
    pub screenshots: bool,
    /// Foxes in the characters scene, 1–1000 (each posed anew every frame).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub characters: u32,
    /// Seconds one run (setup, warm-up and measured frames) may take before the bench
    /// gives up: it keeps the report of the runs before it and exits with status 3 (a
    /// GPU hang, or a pass far over budget, must not eat a lent machine's time). 0: no
    /// limit.
    #[arg(long, default_value_t = 300)]
    pub run_limit: u64,
}

/// `1080p`, `4k`, `tiny` or `WxH`.
fn parse_size(s: &str) -> Result<UVec2, String> {
    match s {
        "1080p" => Ok(UVec2::new(1920, 1080)),
        "4k" | "2160p" => Ok(UVec2::new(3840, 2160)),
        "tiny" => Ok(UVec2::new(160, 90)),
        _ => {
            let (w, h) = s
                .split_once('x')
                .ok_or_else(|| format!("`{s}`: expected 1080p, 4k, tiny or WxH"))?;
            let n = |v: &str| v.parse::<u32>().ok().filter(|&v| (1..=8192).contains(&v));
            match (n(w), n(h)) {
                (Some(w), Some(h)) => Ok(UVec2::new(w, h)),
                _ => Err(format!("`{s}`: sides must be 1 to 8192 pixels")),
            }
        }
    }
}

/// What one run measured.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// The scene.
    pub scene: SceneKind,
    /// The variant.
    pub variant: Variant,
    /// The render size.
    pub size: UVec2,
    /// Wall time of each measured `App::update`, ms.
    pub cpu_frame: Option<Stats>,
    /// CPU time of all Penumbra systems per update, ms (`system_times`).
    pub penumbra_cpu: Option<Stats>,
    /// CPU time of each Penumbra system per update, ms, by system.
    pub systems_cpu: Vec<(String, Stats)>,
    /// The frame timer's GPU time per frame, ms.
    pub frame_gpu: Option<Stats>,
    /// The frame's GPU time cut at the marks, ms per [`measure::SEGMENTS`] entry.
    pub segments: Vec<(&'static str, Stats)>,
    /// Per diagnostic path (`render/<span>/elapsed_gpu|elapsed_cpu`), ms.
    pub diagnostics: Vec<(String, Stats)>,
    /// GPU memory at the end of the run.
    pub memory: Memory,
    /// Object records uploaded per measured frame (Penumbra's apps).
    pub records: Option<Stats>,
    /// Distance fields re-baked per measured frame (`DistanceFieldRebake`).
    pub rebakes: Option<Stats>,
    /// The distance-field atlas at the end of the run (Penumbra's apps with casters).
    pub atlas: Option<AtlasSummary>,
    /// Seconds from startup to ready (loads, bakes).
    pub setup_s: f64,
    /// Updates until ready.
    pub setup_frames: u32,
}

/// How the scene's distance fields sit in the atlas: a field halved or skipped for want
/// of room changes both the run time and the error, so the report says so.
#[derive(Clone, Copy, Debug, Default)]
pub struct AtlasSummary {
    /// Bytes the fields fill.
    pub used_bytes: u64,
    /// The atlas texture's bytes.
    pub texture_bytes: u64,
    /// Fields placed.
    pub volumes: usize,
    /// Of them, as sparse bricks.
    pub bricked: usize,
    /// Of them, at reduced resolution.
    pub downsampled: usize,
    /// Fields that found no room (their casters skipped).
    pub skipped: usize,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let Some(adapter) = penumbra_test::vulkan_adapter() else {
        eprintln!(
            "penumbra-bench: no Vulkan adapter found (install a GPU driver, or Mesa's \
             software one: Debian package `mesa-vulkan-drivers`)"
        );
        return ExitCode::FAILURE;
    };
    let scenes_dir = scenes::scenes_dir(args.scenes_dir.as_deref());
    let scenes: Vec<SceneKind> = if args.scenes.is_empty() {
        SceneKind::ALL.to_vec()
    } else {
        args.scenes.clone()
    };
    for scene in &scenes {
        if let Some(file) = scene.file()
            && !scenes_dir.join(file).is_file()
        {
            eprintln!(
                "penumbra-bench: scene `{}` needs {} (see --scenes-dir)",
                scene.name(),
                scenes_dir.join(file).display()
            );
            return ExitCode::from(2);
        }
    }
    if let Err(e) = std::fs::create_dir_all(&args.out) {
        eprintln!("penumbra-bench: {}: {e}", args.out.display());
        return ExitCode::FAILURE;
    }
    let meta = report::Meta {
        device: args.device.clone().unwrap_or_else(|| adapter.to_owned()),
        frames: args.frames,
        warm_up: args.warm_up,
        command: std::env::args().collect::<Vec<_>>().join(" "),
    };
    let watchdog = Watchdog::start(args.run_limit);
    // A panic (wgpu's device-lost and time-out panics among them) ends the process at
    // once: unwinding past a lost device can block, and the runs before it are on disk.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        default_hook(info);
        eprintln!("penumbra-bench: a run panicked; the runs before it are in the report");
        std::process::exit(101);
    }));
    let mut results = Vec::new();
    for &size in &args.sizes {
        for &scene in &scenes {
            for &variant in scene.variants() {
                if !args.variants.is_empty() && !args.variants.contains(&variant) {
                    continue;
                }
                let run = Run {
                    scene,
                    variant,
                    characters: args.characters,
                    scenes_dir: scenes_dir.clone(),
                };
                eprintln!(
                    "penumbra-bench: {} / {} at {}x{} …",
                    scene.name(),
                    variant.name(),
                    size.x,
                    size.y
                );
                watchdog.arm(format!(
                    "{} / {} at {}x{}",
                    scene.name(),
                    variant.name(),
                    size.x,
                    size.y
                ));
                let outcome = run_one(&args, &run, size, &scenes_dir);
                watchdog.disarm();
                match outcome {
                    Ok(result) => {
                        eprintln!(
                            "penumbra-bench:   ready after {} updates ({:.1} s); GPU frame \
                             median {}",
                            result.setup_frames,
                            result.setup_s,
                            report::frame_gpu(&result)
                                .map_or("n/a".into(), |s| format!("{:.3} ms", s.median))
                        );
                        results.push(result);
                        // After every run, so that a later failure keeps these figures.
                        if let Err(e) = write_report(&args.out, &meta, &results) {
                            eprintln!("penumbra-bench: {e}");
                            return ExitCode::FAILURE;
                        }
                    }
                    Err(e) => {
                        eprintln!("penumbra-bench: {} / {}: {e}", scene.name(), variant.name());
                        return ExitCode::FAILURE;
                    }
                }
            }
        }
    }
    if let Err(e) = write_report(&args.out, &meta, &results) {
        eprintln!("penumbra-bench: {e}");
        return ExitCode::FAILURE;
    }
    let markdown = report::markdown(&meta, &results);
    println!("{markdown}");
    eprintln!(
        "penumbra-bench: wrote {} and {}",
        args.out.join("bench.json").display(),
        args.out.join("bench.md").display()
    );
    ExitCode::SUCCESS
}

/// Writes `bench.json` and `bench.md` for the runs so far.
fn write_report(
    out: &std::path::Path,
    meta: &report::Meta,
    results: &[RunResult],
) -> Result<(), String> {
    let write = |name: &str, text: &str| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))
    };
    let json = report::json(meta, results);
    write(
        "bench.json",
        &serde_json::to_string_pretty(&json).expect("serialisable"),
    )?;
    write("bench.md", &report::markdown(meta, results))
}

/// The run in progress and when it started, watched by [`Watchdog`].
type Current = std::sync::Arc<std::sync::Mutex<Option<(std::time::Instant, String)>>>;

/// Ends the process when one run takes longer than `--run-limit` seconds.
struct Watchdog {
    current: Current,
}

impl Watchdog {
    fn start(limit_s: u64) -> Self {
        let current = Current::default();
        if limit_s > 0 {
            let watched = current.clone();
            let limit = std::time::Duration::from_secs(limit_s);
            std::thread::spawn(move || {
                loop {
                    std::thread::sleep(std::time::Duration::from_millis(250));
                    let guard = watched.lock().unwrap_or_else(|e| e.into_inner());
                    if let Some((start, what)) = &*guard
                        && start.elapsed() > limit
                    {
                        eprintln!(
                            "penumbra-bench: {what} still running after {limit_s} s \
                             (--run-limit): giving up; the runs before it are in the report"
                        );
                        std::process::exit(3);
                    }
                }
            });
        }
        Self { current }
    }

    fn arm(&self, what: String) {
        *self.current.lock().unwrap_or_else(|e| e.into_inner()) =
            Some((std::time::Instant::now(), what));
    }

    fn disarm(&self) {
        *self.current.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }
}

/// Renders one scene in one variant and measures it.
fn run_one(
    args: &Args,
    run: &Run,
    size: UVec2,
    scenes_dir: &std::path::Path,
) -> Result<RunResult, String> {
    use penumbra_test::HeadlessRender;
    let mut render = HeadlessRender::new(size.x, size.y);
    render.asset_root = Some(scenes_dir.to_path_buf());
    let mut app = render.app();
    app.add_plugins(RenderDiagnosticsPlugin);
    measure::add_measurement(&mut app);
    scenes::add_scene(&mut app, run)?;
    app.finish();
    app.cleanup();
    let result = measure_run(args, run, size, &render, &mut app);
    measure::drain_gpu(&app);
    result
}

/// The body of [`run_one`] once its app is built: setup, warm-up, measured frames.
fn measure_run(
    args: &Args,
    run: &Run,
    size: UVec2,
    render: &penumbra_test::HeadlessRender,
    app: &mut App,
) -> Result<RunResult, String> {
    let start = std::time::Instant::now();
    let mut setup_frames = 0;
    const MAX_SETUP: u32 = 3_000;
    while !scenes::scene_ready(app.world_mut()) {
        if setup_frames == MAX_SETUP {
            return Err(format!("not ready after {MAX_SETUP} updates"));
        }
        app.update();
        setup_frames += 1;
        if setup_frames % 200 == 0 {
            eprintln!(
                "penumbra-bench:   still setting up after {setup_frames} updates ({:.0} s): {}",
                start.elapsed().as_secs_f64(),
                scenes::waiting_for(app.world_mut())
            );
        }
    }
    let setup_s = start.elapsed().as_secs_f64();
    for _ in 0..args.warm_up {
        app.update();
    }
    app.world_mut().resource_mut::<Samples>().recording = true;
    let gpu_times = app.world().resource::<measure::FrameGpuTimes>().clone();
    gpu_times.0.lock().expect("not poisoned").clear();
    gpu_times.1.lock().expect("not poisoned").clear();
    let mut cpu = Vec::with_capacity(args.frames as usize);
    let mut systems = measure::SystemSeries::start();
    let (mut records, mut rebakes) = (Vec::new(), Vec::new());
    for _ in 0..args.frames {
        let t = std::time::Instant::now();
        app.update();
        cpu.push(t.elapsed().as_secs_f64() * 1e3);
        systems.take_frame();
        let world = app.world();
        if let Some(u) = world.get_resource::<penumbra::prelude::DistanceFieldUploadStats>() {
            records.push(u.frame_records as f64);
        }
        if let Some(r) = world.get_resource::<penumbra::prelude::DistanceFieldRebakeStats>() {
            rebakes.push(r.bakes as f64);
        }
    }
    let (penumbra_cpu, systems_cpu) = systems.finish();
    // Render diagnostics arrive a few frames late: keep taking them, not the frames.
    let probe = app.world().resource::<measure::MemoryProbe>().clone();
    probe.request();
    let mut memory = None;
    for _ in 0..6 {
        app.update();
        memory = memory.or_else(|| probe.take());
    }
    let atlas = app
        .world()
        .get_resource::<penumbra::prelude::DistanceFieldUploadStats>()
        .filter(|u| u.atlas_bytes > 0)
        .map(|u| AtlasSummary {
            used_bytes: u.atlas_used_bytes,
            texture_bytes: u.atlas_bytes,
            volumes: u.atlas_volumes,
            bricked: u.atlas_bricked,
            downsampled: u.atlas_downsampled,
            skipped: u.atlas_skipped,
        });
    let samples = std::mem::take(&mut app.world_mut().resource_mut::<Samples>().series);
    let mut frame_gpu = std::mem::take(&mut *gpu_times.0.lock().expect("not poisoned"));
    frame_gpu.truncate(args.frames as usize);
    let mut segment_times = std::mem::take(&mut *gpu_times.1.lock().expect("not poisoned"));
    segment_times.truncate(args.frames as usize);
    let segments = measure::SEGMENTS
        .iter()
        .enumerate()
        .filter_map(|(k, name)| {
            let v: Vec<f64> = segment_times.iter().map(|s| s[k]).collect();
            Some((*name, Stats::of(&v)?))
        })
        .collect();
    if args.screenshots {
        let name = format!(
            "{}-{}-{}x{}.png",
            run.scene.name(),
            run.variant.name(),
            size.x,
            size.y
        );
        report::screenshot(app, render, &args.out.join(name))?;
    }
    let frames = args.frames as usize;
    let diagnostics = samples
        .into_iter()
        .filter_map(|(path, mut values)| {
            // At most one value per measured frame (the late ones are of those frames).
            values.truncate(frames);
            Some((path, Stats::of(&values)?))
        })
        .collect();
    Ok(RunResult {
        scene: run.scene,
        variant: run.variant,
        size,
        cpu_frame: Stats::of(&cpu),
        penumbra_cpu,
        systems_cpu,
        frame_gpu: Stats::of(&frame_gpu),
        segments,
        diagnostics,
        memory: memory.unwrap_or_default(),
        records: Stats::of(&records),
        rebakes: Stats::of(&rebakes),
        atlas,
        setup_s,
        setup_frames,
    })
}

#[cfg(test)]
mod tests {
    use super::parse_size;
    use bevy::math::UVec2;

    #[test]
    fn sizes_by_name_or_wxh() {
        assert_eq!(parse_size("1080p"), Ok(UVec2::new(1920, 1080)));
        assert_eq!(parse_size("4k"), Ok(UVec2::new(3840, 2160)));
        assert_eq!(parse_size("tiny"), Ok(UVec2::new(160, 90)));
        assert_eq!(parse_size("640x360"), Ok(UVec2::new(640, 360)));
        for bad in ["0x10", "10x0", "9000x10", "12", "axb", ""] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_report_warns_of_a_cpu_drivers_compute_spans() {
        let lavapipe = "llvmpipe (LLVM 15.0.6, 256 bits) (Cpu, driver llvmpipe Mesa 22.3.6)";
        let h200 = "NVIDIA H200 (DiscreteGpu, driver NVIDIA 570.0)";
        assert!(super::report::cpu_driver_note(lavapipe).is_some());
        assert!(super::report::cpu_driver_note(h200).is_none());
    }
}
