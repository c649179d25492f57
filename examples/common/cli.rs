//! The command line every Penumbra example shares:
//!
//! ```text
//! cargo run --example NAME                          # a window (if a display exists)
//! cargo run --example NAME -- --headless --frames 30 --out NAME.png
//! ```
//!
//! Flags: `--headless` (render into an image, no window; the default when neither
//! `DISPLAY` nor `WAYLAND_DISPLAY` is set), `--frames N` (frames before the capture;
//! in a window, exit after N frames), `--out PATH` (PNG to write; headless default
//! `NAME.png`), `--size WxH` (default 256x256 headless, 1280x720 windowed), `--lights N`
//! (examples with distance-field-shadowed lights: how many, 1..=8; see each example),
//! `--glass` (`df_shadows`: add an alpha-blended pane, which Bevy lights in its forward
//! pass, so the distance-field-shadowed lights keep their shadow maps for it),
//! `--plain` (without Penumbra's distance-field effects: the lights' shadows are Bevy's
//! shadow maps and there is no DFAO — the "before" image), `--ao-view V` (examples with
//! DFAO: its debug view, `ao`, `bent` or `tiles`), `--casters N` (`dfao`: N extra small
//! casters, to see how the cost grows), `--global-field` (`dfao`: a
//! `GlobalDistanceField` on the camera, the cones' far part traced through it, and a
//! fountain of particles colliding with it), `--msaa off|4|every|edges`
//! (`deferred_msaa`: MSAA off, deferred 4× classified — the default —, every sample
//! shaded, or the per-sample mask's debug view), `--dof penumbra|circle|bevy-bokeh|
//! bevy-gaussian|off` (`bokeh_dof`: Penumbra's scatter bokeh, hexagonal or circular, Bevy's
//! `DepthOfField` in either mode, or none), `--no-sss` (`subsurface`: without
//! `SubsurfaceScattering`, the skin lit as an ordinary material), `--no-reflections`
//! (`reflections`: without `BillboardReflections`), `--assets DIR` (the asset
//! folder; default Bevy's `assets`, or the example's own).
//!
//! Windowed runs take keyboard toggles (`controls.rs`: `Space` distance-field shadows,
//! `H` half resolution, `D` debug view), shown in the window title.
//!
//! Headless runs print the mean frame time, what Penumbra allocated on the GPU per
//! frame (`PenumbraGpuAllocations`; pooled resources: 0 once the scene is steady) and
//! how many shadow-map passes Bevy rendered per frame (cascades, cube faces, spots), and
//! the mean GPU time of each of Penumbra's passes (`render/penumbra_*/elapsed_gpu`, from
//! Bevy's `RenderDiagnosticsPlugin`; lavapipe's timestamps on a machine without a GPU).

use bevy::{
    prelude::*,
    render::view::screenshot::{Screenshot, save_to_disk},
    window::WindowResolution,
};
use std::path::PathBuf;

#[path = "controls.rs"]
mod controls;

/// Command-line options (also a resource of the example's app).
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct Options {
    /// Render into an image instead of a window.
    pub headless: bool,
    /// Frames to render before the capture (headless) or before exiting (windowed).
    pub frames: Option<u32>,
    /// Where to write the PNG.
    pub out: Option<PathBuf>,
    /// Image or window size in pixels.
    pub size: Option<UVec2>,
    /// Distance-field-shadowed lights, for examples that have them.
    pub lights: Option<u32>,
    /// Add an alpha-blended pane (a consumer of the lights' shadow maps).
    pub glass: bool,
    /// Remove every `DistanceFieldShadows` and `DistanceFieldAmbientOcclusion` after
    /// the scene spawns.
    pub plain: bool,
    /// The DFAO debug view of every camera that has DFAO.
    pub ao_view: Option<penumbra::prelude::DistanceFieldAoDebugView>,
    /// Extra casters, for examples that scale (`dfao`).
    pub casters: Option<u32>,
    /// Put a `GlobalDistanceField` on the DFAO cameras (`dfao`): their cones go on
    /// through it beyond `global_field_start`.
    pub global_field: bool,
    /// `--no-dfao component|plugin`: remove every `DistanceFieldAmbientOcclusion` after
    /// the scene spawns (distance-field shadows stay); with `plugin` the `dfao` example
    /// also builds `PenumbraPlugins` without `DistanceFieldAmbientOcclusionPlugin` (the
    /// other examples treat it as `component`) — the two runs measure what the plugin
    /// costs a scene that does not use it.
    pub no_dfao: Option<NoDfao>,
    /// `--msaa`: the deferred MSAA mode of examples that show it (`deferred_msaa`).
    pub msaa: Option<MsaaMode>,
    /// `--dof`: the depth of field of examples that compare them (`bokeh_dof`).
    pub dof: Option<DofMode>,
    /// `--no-sss`: remove every `SubsurfaceScattering` after the scene spawns.
    pub no_sss: bool,
    /// `--no-reflections`: the `reflections` example's camera without
    /// `BillboardReflections`.
    pub no_reflections: bool,
    /// `--hair`: how the `hair` example's strands decide coverage.
    pub hair: Option<HairMode>,
    /// `--tessellation`: the `tessellation` example's surface.
    pub tessellation: Option<TessellationChoice>,
    /// `--assets`: the asset folder (`AssetPlugin::file_path`).
    pub assets: Option<PathBuf>,
}

/// What `--tessellation` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TessellationChoice {
    /// The input mesh, untessellated.
    Off,
    /// Flat patches, displaced.
    Flat,
    /// PN-AEN patches, displaced (the default).
    PnAen,
    /// PN-AEN patches with Bevy's wireframe drawn over them.
    Wireframe,
}

/// What `--dof` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DofMode {
    /// Penumbra's `BokehDepthOfField`, hexagonal aperture.
    Penumbra,
    /// Penumbra's `BokehDepthOfField`, circular aperture.
    PenumbraCircle,
    /// Bevy's `DepthOfField`, bokeh mode.
    BevyBokeh,
    /// Bevy's `DepthOfField`, Gaussian mode.
    BevyGaussian,
    /// No depth of field.
    Off,
}

/// What `--msaa` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MsaaMode {
    /// `Msaa::Off`.
    Off,
    /// Deferred 4×, classified.
    Classified,
    /// Deferred 4×, every sample shaded.
    EverySample,
    /// Deferred 4×, classified, per-sample pixels tinted (`DeferredMsaa::show_edges`).
    Edges,
}

/// What `--hair` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HairMode {
    /// The alpha tested at each MSAA sample (the default).
    PerSample,
    /// Shaded and tested per sample.
    SampleShading,
    /// Alpha-to-coverage.
    AlphaToCoverage,
    /// One alpha test per pixel.
    PerPixel,
    /// No hair.
    Off,
}

/// What `--no-dfao` leaves out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoDfao {
    /// The component (the plugin stays).
    Component,
    /// The component and the plugin.
    Plugin,
}

const USAGE: &str = "usage: EXAMPLE [--headless] [--frames N] [--out PATH] [--size WxH] [--lights N] [--glass] \
     [--plain] [--ao-view ao|bent|tiles] [--casters N] [--global-field] [--no-dfao component|plugin] [--msaa off|4|every|edges] \
     [--dof penumbra|circle|bevy-bokeh|bevy-gaussian|off] [--no-sss] [--no-reflections] \
     [--hair per-sample|sample-shading|alpha-to-coverage|per-pixel|off] [--tessellation off|flat|pn-aen|wireframe] [--assets DIR]";

impl Options {
    /// Parses `std::env::args()`-style arguments (without the program name).
    pub fn parse(args: impl IntoIterator<Item = String>) -> Result<Self, String> {
        let mut o = Options {
            headless: false,
            frames: None,
            out: None,
            size: None,
            lights: None,
            glass: false,
            plain: false,
            ao_view: None,
            casters: None,
            global_field: false,
            no_dfao: None,
            msaa: None,
            dof: None,
            no_sss: false,
            no_reflections: false,
            hair: None,
            tessellation: None,
            assets: None,
        };
        let mut args = args.into_iter();
        while let Some(arg) = args.next() {
            let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
            match arg.as_str() {
                "--headless" => o.headless = true,
                "--glass" => o.glass = true,
                "--plain" => o.plain = true,
                "--no-sss" => o.no_sss = true,
                "--no-reflections" => o.no_reflections = true,
                "--global-field" => o.global_field = true,
                "--casters" => {
                    let v = value("--casters")?;
                    match v.parse::<u32>() {
                        Ok(n) if n <= 100_000 => o.casters = Some(n),
                        _ => return Err(format!("--casters must be in 0..=100000, got {v:?}")),
                    }
                }
                "--no-dfao" => {
                    o.no_dfao = Some(match value("--no-dfao")?.as_str() {
                        "component" => NoDfao::Component,
                        "plugin" => NoDfao::Plugin,
                        v => return Err(format!("--no-dfao: component or plugin, got {v:?}")),
                    });
                }
                "--msaa" => {
                    o.msaa = Some(match value("--msaa")?.as_str() {
                        "off" => MsaaMode::Off,
                        "4" => MsaaMode::Classified,
                        "every" => MsaaMode::EverySample,
                        "edges" => MsaaMode::Edges,
                        v => return Err(format!("--msaa: off, 4, every or edges, got {v:?}")),
                    });
                }
                "--hair" => {
                    o.hair = Some(match value("--hair")?.as_str() {
                        "per-sample" => HairMode::PerSample,
                        "sample-shading" => HairMode::SampleShading,
                        "alpha-to-coverage" => HairMode::AlphaToCoverage,
                        "per-pixel" => HairMode::PerPixel,
                        "off" => HairMode::Off,
                        v => {
                            return Err(format!(
                                "--hair: per-sample, sample-shading, alpha-to-coverage, per-pixel or off, got {v:?}"
                            ));
                        }
                    });
                }
                "--tessellation" => {
                    o.tessellation = Some(match value("--tessellation")?.as_str() {
                        "off" => TessellationChoice::Off,
                        "flat" => TessellationChoice::Flat,
                        "pn-aen" => TessellationChoice::PnAen,
                        "wireframe" => TessellationChoice::Wireframe,
                        v => {
                            return Err(format!(
                                "--tessellation: off, flat, pn-aen or wireframe, got {v:?}"
                            ));
                        }
                    });
                }
                "--dof" => {
                    o.dof = Some(match value("--dof")?.as_str() {
                        "penumbra" => DofMode::Penumbra,
                        "circle" => DofMode::PenumbraCircle,
                        "bevy-bokeh" => DofMode::BevyBokeh,
                        "bevy-gaussian" => DofMode::BevyGaussian,
                        "off" => DofMode::Off,
                        v => {
                            return Err(format!(
                                "--dof: penumbra, circle, bevy-bokeh, bevy-gaussian or off, got {v:?}"
                            ));
                        }
                    });
                }
                "--assets" => o.assets = Some(PathBuf::from(value("--assets")?)),
                "--ao-view" => {
                    use penumbra::prelude::DistanceFieldAoDebugView as View;
                    o.ao_view = Some(match value("--ao-view")?.as_str() {
                        "ao" => View::AmbientOcclusion,
                        "bent" => View::BentNormal,
                        "tiles" => View::ObjectsPerTile,
                        v => return Err(format!("--ao-view: ao, bent or tiles, got {v:?}")),
                    });
                }
                "--frames" => {
                    let v = value("--frames")?;
                    let n: u32 = v
                        .parse()
                        .map_err(|_| format!("--frames: bad number {v:?}"))?;
                    if n == 0 || n > 100_000 {
                        return Err(format!("--frames must be in 1..=100000, got {n}"));
                    }
                    o.frames = Some(n);
                }
                "--out" => o.out = Some(PathBuf::from(value("--out")?)),
                "--size" => {
                    let v = value("--size")?;
                    let (w, h) = v
                        .split_once('x')
                        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
                        .ok_or(format!("--size: expected WxH, got {v:?}"))?;
                    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
                        return Err(format!("--size must be within 1..=8192 per axis, got {v}"));
                    }
                    o.size = Some(UVec2::new(w, h));
                }
                "--lights" => {
                    let v = value("--lights")?;
                    match v.parse::<u32>() {
                        Ok(n @ 1..=8) => o.lights = Some(n),
                        _ => return Err(format!("--lights must be in 1..=8, got {v:?}")),
                    }
                }
                "-h" | "--help" => return Err(USAGE.to_string()),
                other => return Err(format!("unknown argument {other:?}\n{USAGE}")),
            }
        }
        Ok(o)
    }
}

/// Whether a display server is reachable (an X11 or Wayland socket named in the env).
fn display_available() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// The example's `main`: parses the arguments, then renders headless or in a window
/// with `scene` (plugins and systems added to a Bevy app with Penumbra's plugins).
#[allow(dead_code, reason = "tests include the examples without their main")]
pub fn main(
    name: &str,
    scene: fn(&mut App),
    ready: Option<fn(&mut World) -> bool>,
) -> std::process::ExitCode {
    main_in(name, scene, ready, None)
}

/// [`main`] for an example whose assets are in `assets` unless `--assets` says otherwise.
#[allow(dead_code, reason = "only some examples have their own asset folder")]
pub fn main_with_assets(
    name: &str,
    scene: fn(&mut App),
    ready: Option<fn(&mut World) -> bool>,
    assets: PathBuf,
) -> std::process::ExitCode {
    main_in(name, scene, ready, Some(assets))
}

fn main_in(
    name: &str,
    scene: fn(&mut App),
    ready: Option<fn(&mut World) -> bool>,
    assets: Option<PathBuf>,
) -> std::process::ExitCode {
    let mut options = match Options::parse(std::env::args().skip(1)) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("{e}");
            return std::process::ExitCode::from(2);
        }
    };
    if options.assets.is_none() {
        options.assets = assets;
    }
    let headless = options.headless || !display_available();
    if headless && !options.headless {
        println!("{name}: no display (DISPLAY/WAYLAND_DISPLAY unset); rendering headless");
    }
    let result = if headless {
        run_headless(name, &options, scene, ready)
    } else {
        run_windowed(name, &options, scene);
        Ok(())
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Renders into an image on whatever Vulkan adapter exists and writes a PNG. `ready`:
/// updates run until it holds before the counted frames (background work such as SDF
/// bakes done), so the capture does not depend on the machine's speed.
pub fn run_headless(
    name: &str,
    options: &Options,
    scene: fn(&mut App),
    ready: Option<fn(&mut World) -> bool>,
) -> Result<(), String> {
    use penumbra_test::{HeadlessRender, vulkan_adapter};
    let Some(adapter) = vulkan_adapter() else {
        return Err(
            "no Vulkan adapter found. Install Mesa's software Vulkan driver, \
                    Debian package `mesa-vulkan-drivers` (`cargo xtask showcase` does it)"
                .into(),
        );
    };
    let size = options.size.unwrap_or(UVec2::splat(256));
    let frames = options.frames.unwrap_or(30);
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{name}.png")));
    let mut render = HeadlessRender::new(size.x, size.y).frames(frames);
    render.warm_up = ready;
    render.asset_root = options.assets.clone();
    let mut app = render.app();
    app.insert_resource(options.clone())
        .add_systems(PostStartup, apply_options)
        .init_resource::<AllocationLog>()
        .add_systems(Last, log_allocations);
    let shadow_passes = ShadowPassCount::default();
    if let Some(render_app) = app.get_sub_app_mut(bevy::render::RenderApp) {
        render_app
            .insert_resource(shadow_passes.clone())
            .add_systems(
                bevy::render::Render,
                count_shadow_passes.in_set(bevy::render::RenderSystems::Queue),
            );
    }
    app.add_plugins(bevy::render::diagnostic::RenderDiagnosticsPlugin);
    scene(&mut app);
    let (capture, app) = render.run_keeping_app(app).map_err(|e| e.to_string())?;
    print_pass_times(name, app.world());
    capture
        .to_rgba8()
        .save(&out)
        .map_err(|e| format!("writing {}: {e}", out.display()))?;
    let steady = &capture.frame_times[capture.frame_times.len().min(1)..];
    let mean_ms = if steady.is_empty() {
        f64::NAN
    } else {
        steady.iter().map(|d| d.as_secs_f64()).sum::<f64>() * 1e3 / steady.len() as f64
    };
    let path = std::fs::canonicalize(&out).unwrap_or(out);
    println!(
        "{name}: {frames} frames at {}x{} on {adapter}; mean frame time after the first: {mean_ms:.1} ms",
        size.x, size.y
    );
    // Per-frame GPU allocations over the counted frames (and the readback's), the first
    // two left out (the render world runs a frame behind).
    let log = &app.world().resource::<AllocationLog>().0;
    let steady = log.len().saturating_sub(frames as usize).max(2);
    if let (Some(first), Some(last)) = (log.get(steady), log.last()) {
        let n = (log.len() - 1 - steady).max(1) as f64;
        let d = *last - *first;
        println!(
            "{name}: Penumbra GPU allocations per frame over the last {n} frames: {:.2} \
             buffers ({:.0} bytes), {:.2} bind groups, {:.2} textures",
            d.buffers as f64 / n,
            d.buffer_bytes as f64 / n,
            d.bind_groups as f64 / n,
            d.textures as f64 / n
        );
    }
    let (passes, counted) = shadow_passes.totals();
    println!(
        "{name}: Bevy shadow-map passes per frame: {:.2}",
        passes as f64 / counted.max(1) as f64
    );
    println!("{name}: wrote {}", path.display());
    Ok(())
}

/// Shadow-map passes (Bevy's `ShadowView`s) summed over frames, and frames counted:
/// shared by the render world, which counts, and the report.
#[derive(Resource, Clone, Default)]
struct ShadowPassCount(std::sync::Arc<[std::sync::atomic::AtomicU64; 2]>);

impl ShadowPassCount {
    fn totals(&self) -> (u64, u64) {
        use std::sync::atomic::Ordering::Relaxed;
        (self.0[0].load(Relaxed), self.0[1].load(Relaxed))
    }
}

fn count_shadow_passes(views: Query<(), With<bevy::pbr::ShadowView>>, count: Res<ShadowPassCount>) {
    use std::sync::atomic::Ordering::Relaxed;
    count.0[0].fetch_add(views.iter().count() as u64, Relaxed);
    count.0[1].fetch_add(1, Relaxed);
}

/// `PenumbraGpuAllocations` after each frame.
#[derive(Resource, Default)]
struct AllocationLog(Vec<penumbra::df::GpuAllocationCounts>);

fn log_allocations(
    allocations: Option<Res<penumbra::df::PenumbraGpuAllocations>>,
    mut log: ResMut<AllocationLog>,
) {
    if let Some(a) = allocations {
        log.0.push(a.counts());
    }
}

/// Whether every caster is in the distance-field scene (mesh casters' SDFs baked and
/// placed): the examples' animations wait for it, and headless captures count frames
/// from it (`dfao` waits on its own `rolling`, which also aligns DFAO's jitter).
#[allow(dead_code, reason = "the dfao example waits on its own condition")]
pub fn casters_ready(world: &mut World) -> bool {
    use penumbra::prelude::{DistanceFieldCaster, DistanceFieldScene};
    let casters: Vec<Entity> = world
        .query_filtered::<Entity, With<DistanceFieldCaster>>()
        .iter(world)
        .collect();
    let Some(scene) = world.get_resource::<DistanceFieldScene>() else {
        return false;
    };
    !casters.is_empty() && casters.iter().all(|&e| scene.slot(e).is_some())
}

/// [`casters_ready`] on a frame that is a multiple of 4, DFAO's jitter cycle: for still
/// scenes with DFAO (the showcase), so that a capture a given number of frames later
/// always sees the same jitter position however long the bakes took.
#[allow(dead_code, reason = "used by the still scenes with DFAO only")]
pub fn casters_ready_in_phase(world: &mut World) -> bool {
    world
        .get_resource::<bevy::diagnostic::FrameCount>()
        .is_some_and(|f| f.0.is_multiple_of(4))
        && casters_ready(world)
}

/// The mean GPU time of each of Penumbra's passes over the last frames.
fn print_pass_times(name: &str, world: &World) {
    let Some(store) = world.get_resource::<bevy::diagnostic::DiagnosticsStore>() else {
        return;
    };
    let mut times: Vec<(String, f64)> = store
        .iter()
        .filter_map(|d| {
            let path = d.path().as_str();
            let pass = path.strip_prefix("render/")?.strip_suffix("/elapsed_gpu")?;
            pass.starts_with("penumbra")
                .then(|| Some((pass.to_string(), d.average()?)))
                .flatten()
        })
        .collect();
    times.sort_by(|a, b| a.0.cmp(&b.0));
    for (pass, ms) in times {
        println!("{name}: GPU time {pass} {ms:.2} ms");
    }
}

/// `--plain`, `--ao-view` and `--global-field`, applied once the scene has spawned.
fn apply_options(
    mut commands: Commands,
    options: Res<Options>,
    shadowed: Query<Entity, With<penumbra::prelude::DistanceFieldShadows>>,
    mut ao: Query<(
        Entity,
        &mut penumbra::prelude::DistanceFieldAmbientOcclusion,
    )>,
) {
    use penumbra::prelude::{DistanceFieldAmbientOcclusion, DistanceFieldShadows};
    for (entity, mut ao) in &mut ao {
        if options.plain || options.no_dfao.is_some() {
            commands
                .entity(entity)
                .remove::<DistanceFieldAmbientOcclusion>();
        } else {
            if let Some(view) = options.ao_view {
                ao.debug_view = view;
            }
            if options.global_field {
                // The field from 1 m: within the example's 3 m reach (the default
                // switch, 3 m, would leave it unused).
                ao.global_field_start = 1.0;
                commands
                    .entity(entity)
                    .insert(penumbra::prelude::GlobalDistanceField::default());
            }
        }
    }
    if options.plain {
        for entity in &shadowed {
            commands.entity(entity).remove::<DistanceFieldShadows>();
        }
    }
}

/// Opens a window; with `--frames N` exits after N frames (saving `--out` if given).
fn run_windowed(name: &str, options: &Options, scene: fn(&mut App)) {
    let size = options.size.unwrap_or(UVec2::new(1280, 720));
    let mut app = App::new();
    let mut assets = AssetPlugin::default();
    if let Some(dir) = &options.assets {
        assets.file_path = dir.to_string_lossy().into_owned();
    }
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window {
                    title: format!("Penumbra {name}"),
                    resolution: WindowResolution::new(size.x, size.y),
                    ..default()
                }),
                ..default()
            })
            .set(assets),
    );
    app.insert_resource(options.clone())
        .add_systems(PostStartup, apply_options);
    scene(&mut app);
    controls::add_controls(&mut app, name);
    if let Some(frames) = options.frames {
        let out = options.out.clone();
        let name = name.to_string();
        app.add_systems(
            Update,
            move |mut commands: Commands, mut n: Local<u32>, mut exit: MessageWriter<AppExit>| {
                *n += 1;
                if *n == frames
                    && let Some(out) = &out
                {
                    println!("{name}: saving {}", out.display());
                    commands
                        .spawn(Screenshot::primary_window())
                        .observe(save_to_disk(out.clone()));
                }
                // Leave a few frames for the screenshot to be written.
                if *n >= frames + 5 {
                    exit.write(AppExit::Success);
                }
            },
        );
    }
    app.run();
}
