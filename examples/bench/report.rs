//! The benchmark's report: JSON with every figure, and a markdown table per size and
//! scene, then Penumbra's features against Bevy's counterparts.
//!
//! A comparison takes each side's own pass where both record one (Bevy's `ssao` and
//! `ssr` against Penumbra's spans). Where Bevy's pass records none (its shadow maps, its
//! depth of field), a side's cost is the frame's GPU time less that of the variant
//! without it (`bevy-no-shadows`, `bevy`) of the same scene and size; the frame totals are compared for
//! renderers (forward against deferred MSAA, Penumbra off or on against plain Bevy).

use super::RunResult;
use super::measure::Stats;
use super::scenes::{SceneKind, Variant};
use bevy::math::UVec2;
use serde_json::{Value, json};
use std::fmt::Write;

/// About the whole benchmark.
pub struct Meta {
    /// The device's name.
    pub device: String,
    /// Frames measured per run.
    pub frames: u32,
    /// Frames of warm-up.
    pub warm_up: u32,
    /// The command line.
    pub command: String,
}

/// The name of a pass from a diagnostic path (`render/<frame>/<pass>/elapsed_gpu`),
/// and whether it is GPU time.
fn pass_of(path: &str) -> Option<(&str, bool)> {
    let rest = path.strip_prefix("render/")?;
    let (name, gpu) = if let Some(n) = rest.strip_suffix("/elapsed_gpu") {
        (n, true)
    } else {
        (rest.strip_suffix("/elapsed_cpu")?, false)
    };
    Some((name, gpu))
}

/// The shader invocations Bevy's pass spans count (pipeline-statistics queries, where
/// the device has them): `(span, kind, per-frame stats)` for Penumbra's spans. A measure
/// of work that does not depend on the device's speed: overdraw, threads dispatched.
fn invocations(r: &RunResult) -> Vec<(&str, &'static str, Stats)> {
    const KINDS: [(&str, &str); 2] = [
        ("/fragment_shader_invocations", "fragment"),
        ("/compute_shader_invocations", "compute"),
    ];
    r.diagnostics
        .iter()
        .filter_map(|(path, s)| {
            let rest = path.strip_prefix("render/")?;
            KINDS.iter().find_map(|(suffix, kind)| {
                let span = rest.strip_suffix(suffix)?;
                (span.starts_with("penumbra") && s.median > 0.0).then_some((span, *kind, *s))
            })
        })
        .collect()
}

/// GPU time of `pass` (exact name) in `r`.
pub fn pass_gpu(r: &RunResult, pass: &str) -> Option<Stats> {
    r.diagnostics
        .iter()
        .find(|(p, _)| pass_of(p) == Some((pass, true)))
        .map(|(_, s)| *s)
}

/// The frame's GPU time (the frame timer's).
pub fn frame_gpu(r: &RunResult) -> Option<Stats> {
    r.frame_gpu
}

/// The sum of the medians of `passes` (those present), if any is.
fn passes_median(r: &RunResult, passes: &[&str]) -> Option<f64> {
    let found: Vec<f64> = passes
        .iter()
        .filter_map(|p| pass_gpu(r, p))
        .map(|s| s.median)
        .collect();
    (!found.is_empty()).then(|| found.iter().sum())
}

/// One feature of Penumbra against Bevy's counterpart, on one scene at one size.
pub struct Comparison {
    /// What is compared.
    pub what: &'static str,
    /// The scene.
    pub scene: SceneKind,
    /// The size.
    pub size: UVec2,
    /// Penumbra's side, ms, and how it was measured.
    pub penumbra: (f64, String),
    /// Bevy's side, ms, and how it was measured.
    pub bevy: (f64, String),
    /// Each side's error against ray-traced truth, where a truth bench measured it.
    pub errors: &'static str,
}

/// Every comparison the runs allow.
pub fn comparisons(results: &[RunResult]) -> Vec<Comparison> {
    let mut out = Vec::new();
    let find = |scene, size, variant| {
        results
            .iter()
            .find(|r| r.scene == scene && r.size == size && r.variant == variant)
    };
    let mut keys: Vec<(SceneKind, (u32, u32))> = results
        .iter()
        .map(|r| (r.scene, (r.size.x, r.size.y)))
        .collect();
    keys.dedup();
    keys.sort();
    keys.dedup();
    for (scene, (w, h)) in keys {
        let size = UVec2::new(w, h);
        let get = |v| find(scene, size, v);
        let frame = |v| get(v).and_then(frame_gpu).map(|s| s.median);
        let delta = |v| Some(frame(v)? - frame(Variant::Bevy)?);
        let mut push = |what, p: Option<(f64, String)>, b: Option<(f64, String)>, errors| {
            if let (Some(penumbra), Some(bevy)) = (p, b) {
                out.push(Comparison {
                    what,
                    scene,
                    size,
                    penumbra,
                    bevy,
                    errors,
                });
            }
        };
        let on = get(Variant::Penumbra);
        push(
            "distance-field shadows / shadow maps",
            on.and_then(|r| passes_median(r, &["penumbra_df_shadows"]))
                .map(|v| (v, "`penumbra_df_shadows`, `penumbra`".into())),
            frame(Variant::Bevy)
                .zip(frame(Variant::BevyNoShadows))
                .map(|(a, b)| a - b)
                .map(|v| (v, "frame, `bevy` − `bevy-no-shadows`".into())),
            "no truth figure for shadow maps yet",
        );
        push(
            "DFAO / SSAO",
            on.and_then(|r| passes_median(r, &["penumbra_dfao", "penumbra_global_field_compose"]))
                .map(|v| (v, "`penumbra_dfao` + global field, `penumbra`".into())),
            get(Variant::BevySsao)
                .and_then(|r| passes_median(r, &["ssao"]))
                .map(|v| (v, "`ssao`, `bevy-ssao`".into())),
            "mean |Δ| against ray-traced AO (benches/dfao_vs_ssao.py, 128²): Cornell box \
             DFAO 0.077 / SSAO 0.318, DepthOfFieldExample 0.075 / 0.100",
        );
        push(
            "lighting pass / Bevy's deferred lighting",
            on.and_then(|r| passes_median(r, &["penumbra_lighting"]))
                .map(|v| (v, "`penumbra_lighting`, `penumbra`".into())),
            get(Variant::Bevy)
                .and_then(|r| {
                    let name = crate::measure::SEGMENTS[1];
                    r.segments.iter().find(|s| s.0 == name)
                })
                .map(|(_, s)| {
                    (
                        s.median,
                        "frame: main pass up to the opaque pass, `bevy`".into(),
                    )
                }),
            "the same shading as Bevy's (bevy_penumbra_df/tests/lighting.rs), plus DF \
             shadows and DFAO",
        );
        push(
            "scatter bokeh / Bevy's bokeh depth of field",
            delta(Variant::ScatterBokeh).map(|v| (v, "frame − `bevy`".into())),
            delta(Variant::BevyDof).map(|v| (v, "frame − `bevy`".into())),
            "tests/bokeh_truth.rs (thin-lens truth)",
        );
        push(
            "deferred 4× MSAA / forward 4× MSAA",
            frame(Variant::DeferredMsaa4).map(|v| (v, "frame, `deferred-msaa4`".into())),
            frame(Variant::ForwardMsaa4).map(|v| (v, "frame, `forward-msaa4`".into())),
            "",
        );
        push(
            "billboard reflections / SSR",
            on.and_then(|r| passes_median(r, &["penumbra_billboard_reflections"]))
                .map(|v| (v, "`penumbra_billboard_reflections`, `penumbra`".into())),
            get(Variant::BevySsr)
                .and_then(|r| passes_median(r, &["ssr"]))
                .map(|v| (v, "`ssr`, `bevy-ssr`".into())),
            "",
        );
        push(
            "Penumbra off / plain Bevy",
            frame(Variant::PenumbraOff).map(|v| (v, "frame, `penumbra-off`".into())),
            frame(Variant::Bevy).map(|v| (v, "frame, `bevy`".into())),
            "",
        );
        push(
            "Penumbra on / plain Bevy",
            frame(Variant::Penumbra).map(|v| (v, "frame, `penumbra`".into())),
            frame(Variant::Bevy).map(|v| (v, "frame, `bevy`".into())),
            "",
        );
    }
    out
}

fn stats_json(s: Option<Stats>) -> Value {
    s.map_or(
        Value::Null,
        |s| json!({ "median_ms": s.median, "p95_ms": s.p95, "mean_ms": s.mean, "frames": s.n }),
    )
}

/// Every figure, as JSON.
pub fn json(meta: &Meta, results: &[RunResult]) -> Value {
    let runs: Vec<Value> = results
        .iter()
        .map(|r| {
            let mut passes = serde_json::Map::new();
            for (path, s) in &r.diagnostics {
                if let Some((name, gpu)) = pass_of(path) {
                    let name = if name.is_empty() { "frame" } else { name };
                    let entry = passes.entry(name).or_insert_with(|| json!({}));
                    entry[if gpu { "gpu" } else { "cpu" }] = stats_json(Some(*s));
                }
            }
            json!({
                "scene": r.scene.name(),
                "variant": r.variant.name(),
                "width": r.size.x,
                "height": r.size.y,
                "frame_gpu": stats_json(frame_gpu(r)),
                "frame_gpu_segments": r
                    .segments
                    .iter()
                    .map(|(name, s)| ((*name).to_owned(), stats_json(Some(*s))))
                    .collect::<serde_json::Map<_, _>>(),
                "frame_cpu_wall": stats_json(r.cpu_frame),
                "penumbra_systems_cpu": stats_json(r.penumbra_cpu),
                "systems_cpu": r
                    .systems_cpu
                    .iter()
                    .map(|(name, s)| (name.clone(), stats_json(Some(*s))))
                    .collect::<serde_json::Map<_, _>>(),
                "passes": passes,
                "invocations": invocations(r)
                    .into_iter()
                    .map(|(span, kind, s)| json!({ "span": span, "kind": kind, "median": s.median, "p95": s.p95 }))
                    .collect::<Vec<_>>(),
                "records_per_frame": r.records.map(|s| json!({ "median": s.median, "p95": s.p95, "mean": s.mean })),
                "rebakes_per_frame": r.rebakes.map(|s| json!({ "median": s.median, "p95": s.p95, "mean": s.mean })),
                "penumbra_gpu_bytes": r.memory.penumbra_bytes,
                "penumbra_gpu_allocations": r.memory.penumbra_allocations,
                "total_gpu_bytes": r.memory.total_bytes,
                "atlas": r.atlas.map(|a| json!({
                    "used_bytes": a.used_bytes,
                    "texture_bytes": a.texture_bytes,
                    "volumes": a.volumes,
                    "bricked": a.bricked,
                    "downsampled": a.downsampled,
                    "skipped": a.skipped,
                })),
                "setup_seconds": r.setup_s,
                "setup_updates": r.setup_frames,
            })
        })
        .collect();
    let comparisons: Vec<Value> = comparisons(results)
        .iter()
        .map(|c| {
            json!({
                "what": c.what,
                "scene": c.scene.name(),
                "width": c.size.x,
                "height": c.size.y,
                "penumbra_ms": c.penumbra.0,
                "penumbra_source": c.penumbra.1,
                "bevy_ms": c.bevy.0,
                "bevy_source": c.bevy.1,
                "ratio": (c.penumbra.0 > 0.0 && c.bevy.0 > 0.0).then(|| c.penumbra.0 / c.bevy.0),
                "errors": c.errors,
            })
        })
        .collect();
    json!({
        "device": meta.device,
        "frames": meta.frames,
        "warm_up": meta.warm_up,
        "command": meta.command,
        "runs": runs,
        "comparisons": comparisons,
    })
}

fn ms(s: Option<Stats>) -> String {
    s.map_or("–".into(), |s| format!("{:.3} / {:.3}", s.median, s.p95))
}

fn mib(bytes: u64) -> String {
    format!("{:.1}", bytes as f64 / (1024.0 * 1024.0))
}

/// What a CPU driver's pass times mean, for a device line that names one (wgpu's
/// adapter type `Cpu`: Mesa's lavapipe). llvmpipe stamps a timestamp query when it
/// rasterizes its current scene, not when the queue reaches the query: once a frame has
/// drawn, both ends of a span around a compute pass are stamped after the compute has
/// run, so the span reads near 0 and the compute's time falls outside every span
/// (measured with Mesa 22.3; BENCHMARKS.md). The frame's GPU time is right.
pub fn cpu_driver_note(device: &str) -> Option<&'static str> {
    device.contains("(Cpu").then_some(
        "**A CPU driver:** llvmpipe stamps timestamps when it rasterizes, so a span \
         around a compute pass after the frame's first draw reads near 0 and the \
         compute's time falls between spans: compute spans here under-count (the frame's \
         GPU time does not). Profile the driver's threads (`perf`) to split it.",
    )
}

/// The markdown report: per size and scene, each pass's GPU time (median / p95, ms) in
/// each variant; then the comparisons.
pub fn markdown(meta: &Meta, results: &[RunResult]) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "Device: {}. {} frames measured per run after the scene's bakes and {} warm-up \
         frames. Command: `{}`.\n",
        meta.device, meta.frames, meta.warm_up, meta.command
    );
    if let Some(note) = cpu_driver_note(&meta.device) {
        let _ = writeln!(md, "{note}\n");
    }
    let mut groups: Vec<(UVec2, SceneKind)> = Vec::new();
    for r in results {
        if !groups.contains(&(r.size, r.scene)) {
            groups.push((r.size, r.scene));
        }
    }
    for (size, scene) in groups {
        let runs: Vec<&RunResult> = results
            .iter()
            .filter(|r| r.size == size && r.scene == scene)
            .collect();
        let _ = writeln!(
            md,
            "### {} at {}×{} — GPU ms, median / p95\n",
            scene.name(),
            size.x,
            size.y
        );
        let header: Vec<&str> = runs.iter().map(|r| r.variant.name()).collect();
        let _ = writeln!(md, "| pass | {} |", header.join(" | "));
        let _ = writeln!(md, "|---|{}", "---|".repeat(runs.len()));
        let row = |md: &mut String, name: &str, cells: Vec<String>| {
            let _ = writeln!(md, "| {name} | {} |", cells.join(" | "));
        };
        row(
            &mut md,
            "**frame (GPU)**",
            runs.iter().map(|r| ms(frame_gpu(r))).collect(),
        );
        for name in crate::measure::SEGMENTS {
            let cells: Vec<String> = runs
                .iter()
                .map(|r| ms(r.segments.iter().find(|s| s.0 == name).map(|s| s.1)))
                .collect();
            if cells.iter().any(|c| c != &ms(None)) {
                row(&mut md, &format!("  frame: {name}"), cells);
            }
        }
        row(
            &mut md,
            "frame (CPU wall)",
            runs.iter().map(|r| ms(r.cpu_frame)).collect(),
        );
        row(
            &mut md,
            "Penumbra systems (CPU)",
            runs.iter().map(|r| ms(r.penumbra_cpu)).collect(),
        );
        let mut passes: Vec<&str> = runs
            .iter()
            .flat_map(|r| r.diagnostics.iter())
            .filter_map(|(p, _)| pass_of(p))
            .filter(|(n, gpu)| *gpu && !n.is_empty())
            .map(|(n, _)| n)
            .collect();
        passes.sort_unstable();
        passes.dedup();
        for pass in passes {
            row(
                &mut md,
                &format!("`{pass}`"),
                runs.iter().map(|r| ms(pass_gpu(r, pass))).collect(),
            );
        }
        let mut counted: Vec<(&str, &str)> = runs
            .iter()
            .flat_map(|r| invocations(r))
            .map(|(span, kind, _)| (span, kind))
            .collect();
        counted.sort_unstable();
        counted.dedup();
        for (span, kind) in counted {
            row(
                &mut md,
                &format!("`{span}`: {kind} invocations, millions"),
                runs.iter()
                    .map(|r| {
                        invocations(r)
                            .iter()
                            .find(|(s, k, _)| *s == span && *k == kind)
                            .map_or("–".into(), |(_, _, s)| format!("{:.3}", s.median * 1e-6))
                    })
                    .collect(),
            );
        }
        let count = |s: Option<Stats>| s.map_or("–".into(), |s| format!("{:.0}", s.median));
        if runs.iter().any(|r| r.records.is_some_and(|s| s.mean > 0.0)) {
            row(
                &mut md,
                "object records uploaded per frame (median)",
                runs.iter().map(|r| count(r.records)).collect(),
            );
        }
        if runs.iter().any(|r| r.rebakes.is_some_and(|s| s.mean > 0.0)) {
            row(
                &mut md,
                "fields re-baked per frame (median)",
                runs.iter().map(|r| count(r.rebakes)).collect(),
            );
        }
        row(
            &mut md,
            "Penumbra GPU memory, MiB (allocations)",
            runs.iter()
                .map(|r| {
                    format!(
                        "{} ({})",
                        mib(r.memory.penumbra_bytes),
                        r.memory.penumbra_allocations
                    )
                })
                .collect(),
        );
        row(
            &mut md,
            "all GPU memory, MiB",
            runs.iter().map(|r| mib(r.memory.total_bytes)).collect(),
        );
        if runs.iter().any(|r| r.atlas.is_some()) {
            row(
                &mut md,
                "distance-field atlas: MiB filled of texture; fields (bricked, halved, skipped)",
                runs.iter()
                    .map(|r| {
                        r.atlas.map_or("–".into(), |a| {
                            format!(
                                "{} of {}; {} ({}, {}, {})",
                                mib(a.used_bytes),
                                mib(a.texture_bytes),
                                a.volumes,
                                a.bricked,
                                a.downsampled,
                                a.skipped
                            )
                        })
                    })
                    .collect(),
            );
        }
        md.push('\n');
        busiest_systems(&mut md, &runs);
    }
    let comparisons = comparisons(results);
    if !comparisons.is_empty() {
        let _ = writeln!(md, "### Penumbra against Bevy (GPU ms, medians)\n");
        let _ = writeln!(
            md,
            "| scene | size | Penumbra / Bevy | Penumbra | Bevy | ratio | error against truth |"
        );
        let _ = writeln!(md, "|---|---|---|---|---|---|---|");
        for c in comparisons {
            // A difference of frame times at or under zero is noise: no ratio.
            let ratio = if c.penumbra.0 > 0.0 && c.bevy.0 > 0.0 {
                format!("{:.2}", c.penumbra.0 / c.bevy.0)
            } else {
                "– (noise)".into()
            };
            let _ = writeln!(
                md,
                "| {} | {}×{} | {} | {:.3} ({}) | {:.3} ({}) | {} | {} |",
                c.scene.name(),
                c.size.x,
                c.size.y,
                c.what,
                c.penumbra.0,
                c.penumbra.1,
                c.bevy.0,
                c.bevy.1,
                ratio,
                c.errors
            );
        }
    }
    md
}

/// The most systems [`busiest_systems`] lists.
const BUSIEST: usize = 12;

/// Penumbra's busiest systems (by their largest median over the runs), CPU ms per
/// update, median / p95, in each run that ran any.
fn busiest_systems(md: &mut String, runs: &[&RunResult]) {
    let runs: Vec<&RunResult> = runs
        .iter()
        .copied()
        .filter(|r| !r.systems_cpu.is_empty())
        .collect();
    if runs.is_empty() {
        return;
    }
    let mut names: Vec<(&str, f64)> = Vec::new();
    for (name, stats) in runs.iter().flat_map(|r| r.systems_cpu.iter()) {
        match names.iter_mut().find(|(n, _)| n == name) {
            Some((_, m)) => *m = m.max(stats.median),
            None => names.push((name, stats.median)),
        }
    }
    names.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(b.0)));
    names.truncate(BUSIEST);
    let header: Vec<&str> = runs.iter().map(|r| r.variant.name()).collect();
    let _ = writeln!(
        md,
        "Penumbra's busiest systems, CPU ms per update, median / p95:\n\n| system | {} |",
        header.join(" | ")
    );
    let _ = writeln!(md, "|---|{}", "---|".repeat(runs.len()));
    for (name, _) in names {
        let cells: Vec<String> = runs
            .iter()
            .map(|r| ms(r.systems_cpu.iter().find(|(n, _)| n == name).map(|s| s.1)))
            .collect();
        let _ = writeln!(md, "| `{name}` | {} |", cells.join(" | "));
    }
    md.push('\n');
}

/// Reads the harness's target back and writes it as a PNG.
pub fn screenshot(
    app: &mut bevy::app::App,
    render: &penumbra_test::HeadlessRender,
    path: &std::path::Path,
) -> Result<(), String> {
    render
        .read_target(app)
        .map_err(|e| e.to_string())?
        .to_rgba8()
        .save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}
