//! Penumbra's render systems run in an order the schedule fixes, not one the executor
//! picks: in the per-camera `Core3d` schedule and the render world's `Render` schedule,
//! no Penumbra system shares data with another system (Penumbra's or Bevy's: bloom,
//! motion blur, auto exposure, screen-space reflections, deferred lighting, ...) without
//! an ordering between the two. Bevy's schedule ambiguity detection, as errors, on an
//! app with every Penumbra plugin and Bevy's post-processing plugins.
//!
//! Passes that meet only in the GPU's command stream (one writes the image or a layer
//! another reads) share no ECS data, so the detection cannot see them: those orderings
//! are checked on the schedule's dependency graph.
//!
//! The main world's schedules are held to the same: a warning reading a camera's `Msaa`
//! runs after `DeferredMsaa` puts it back, a system reading `Mesh3d` changes after Bevy
//! marks them.

use bevy::core_pipeline::schedule::Core3d;
use bevy::ecs::schedule::{InternedScheduleLabel, LogLevel, ScheduleBuildSettings, ScheduleLabel};
use bevy::post_process::auto_exposure::AutoExposurePlugin;
use bevy::prelude::*;
use bevy::render::{Render, RenderApp};
use penumbra::prelude::*;
use penumbra_test::{HeadlessRender, gpu_or_skip};

/// The ambiguous pairs of `label` in `world` that name a Penumbra system: the
/// schedule built with Bevy's ambiguity detection as errors, the pairs read from the
/// error (it lists every ambiguous pair, Bevy's own too).
fn penumbra_ambiguities(world: &mut World, label: InternedScheduleLabel) -> Vec<String> {
    let mut schedule = world
        .resource_mut::<Schedules>()
        .remove(label)
        .unwrap_or_else(|| panic!("no {label:?} schedule"));
    schedule.set_build_settings(ScheduleBuildSettings {
        ambiguity_detection: LogLevel::Error,
        use_shortnames: false,
        ..schedule.get_build_settings()
    });
    let Err(error) = schedule.initialize(world) else {
        return Vec::new();
    };
    let message = error.to_string(schedule.graph(), world);
    assert!(
        message.contains("conflicting data access"),
        "{label:?} does not build: {message}"
    );
    let mut pairs = Vec::new();
    let mut lines = message.lines().peekable();
    while let Some(line) = lines.next() {
        let Some(pair) = line.strip_prefix(" -- ") else {
            continue;
        };
        let on = lines.peek().map_or("", |l| l.trim());
        if pair.contains("penumbra") {
            pairs.push(format!("{pair}; {on}"));
        }
    }
    pairs.sort();
    pairs
}

/// An app with every Penumbra plugin, Bevy's default plugins and auto exposure, built
/// (plugins finished), no frame run.
fn app() -> App {
    let mut app = HeadlessRender::new(64, 64).without_pipelining().app();
    app.add_plugins((PenumbraPlugins, AutoExposurePlugin));
    app.finish();
    app.cleanup();
    app
}

/// A report of the ambiguous pairs naming a Penumbra system in `labels` of `world`.
fn report(world: &mut World, labels: &[InternedScheduleLabel]) -> String {
    let mut report = String::new();
    for &label in labels {
        let pairs = penumbra_ambiguities(world, label);
        if !pairs.is_empty() {
            report += &format!(
                "{label:?}: {} ambiguous pairs\n  {}\n",
                pairs.len(),
                pairs.join("\n  ")
            );
        }
    }
    report
}

#[test]
fn penumbras_render_systems_are_ordered_against_every_system_they_share_data_with() {
    if !gpu_or_skip(
        "penumbras_render_systems_are_ordered_against_every_system_they_share_data_with",
    ) {
        return;
    }
    let mut app = app();
    let world = app.sub_app_mut(RenderApp).world_mut();
    let report = report(world, &[Core3d.intern(), Render.intern()]);
    assert!(report.is_empty(), "{report}");
}

/// The same in the main world's schedules: a warning that reads a camera's `Msaa` while
/// `DeferredMsaa` holds it, a system reading `Mesh3d` changes as Bevy marks them.
#[test]
fn penumbras_main_world_systems_are_ordered_against_every_system_they_share_data_with() {
    if !gpu_or_skip(
        "penumbras_main_world_systems_are_ordered_against_every_system_they_share_data_with",
    ) {
        return;
    }
    let mut app = app();
    let labels = [
        First.intern(),
        PreUpdate.intern(),
        Update.intern(),
        PostUpdate.intern(),
        Last.intern(),
    ];
    let report = report(app.world_mut(), &labels);
    assert!(report.is_empty(), "{report}");
}

/// Whether the dependency graph of `schedule` (initialized) runs every system whose
/// full name contains `first` before every system whose name contains `then`: a path
/// of ordering edges, each edge between sets standing for all their systems.
fn runs_before(schedule: &Schedule, first: &str, then: &str) -> bool {
    use bevy::ecs::schedule::NodeId;
    use std::collections::{HashMap, HashSet};
    let graph = schedule.graph();
    let names: HashMap<NodeId, String> = schedule
        .systems()
        .expect("initialized")
        .map(|(key, system)| (NodeId::System(key), system.name().to_string()))
        .collect();
    // The systems under each node (a system: itself; a set: its members, recursively).
    let hierarchy = graph.hierarchy().graph();
    let members = |node: NodeId| -> Vec<NodeId> {
        let (mut out, mut stack, mut seen) = (Vec::new(), vec![node], HashSet::new());
        while let Some(n) = stack.pop() {
            if !seen.insert(n) {
                continue;
            }
            if names.contains_key(&n) {
                out.push(n);
            }
            stack.extend(hierarchy.neighbors(n));
        }
        out
    };
    let mut after: HashMap<NodeId, HashSet<NodeId>> = HashMap::new();
    for (a, b) in graph.dependency().graph().all_edges() {
        let later = members(b);
        for s in members(a) {
            after.entry(s).or_default().extend(later.iter().copied());
        }
    }
    let select = |part: &str| -> Vec<NodeId> {
        names
            .iter()
            .filter(|(_, name)| name.contains(part))
            .map(|(node, _)| *node)
            .collect()
    };
    let (firsts, thens) = (select(first), select(then));
    assert!(!firsts.is_empty(), "no system named like {first}");
    assert!(!thens.is_empty(), "no system named like {then}");
    firsts.iter().all(|&start| {
        let (mut reached, mut stack) = (HashSet::new(), vec![start]);
        while let Some(n) = stack.pop() {
            for &m in after.get(&n).into_iter().flatten() {
                if reached.insert(m) {
                    stack.push(m);
                }
            }
        }
        thens.iter().all(|t| reached.contains(t))
    })
}

#[test]
fn passes_that_meet_in_the_command_stream_run_in_a_fixed_order() {
    if !gpu_or_skip("passes_that_meet_in_the_command_stream_run_in_a_fixed_order") {
        return;
    }
    let mut app = app();
    let world = app.sub_app_mut(RenderApp).world_mut();
    let mut schedule = world
        .resource_mut::<Schedules>()
        .remove(Core3d)
        .expect("Core3d");
    schedule.initialize(world).expect("Core3d builds");
    // (first, then, why)
    let orders = [
        (
            "distance_field_shadows",
            "penumbra_lighting",
            "the lighting pass reads the masks",
        ),
        (
            "distance_field_ambient_occlusion",
            "penumbra_lighting",
            "the lighting pass reads AO",
        ),
        (
            "billboard_reflections",
            "subsurface_scattering",
            "skin's split lighting reads the specular layer of this frame",
        ),
        (
            "billboard_reflections",
            "penumbra_lighting",
            "the lighting pass reads the specular layer",
        ),
        (
            "penumbra_lighting",
            "subsurface_scattering_msaa",
            "on deferred MSAA views the scatter replaces the lighting pass's shading of skin",
        ),
        (
            "subsurface_scattering_msaa",
            "main_opaque_pass_3d",
            "forward meshes draw over the scattered skin",
        ),
        (
            "deferred_lighting",
            "penumbra_lighting",
            "Penumbra's pass covers Bevy's on its pixels",
        ),
        (
            "penumbra_lighting",
            "screen_space_reflections",
            "SSR reflects the lit image; before the lighting pass, it was overwritten",
        ),
        (
            "bloom::bloom",
            "bokeh_depth_of_field",
            "bloom's glow is blurred with the image",
        ),
        (
            "motion_blur",
            "bokeh_depth_of_field",
            "motion blur before the lens blur",
        ),
        (
            "bokeh_depth_of_field",
            "tonemapping",
            "the blur works on linear HDR",
        ),
    ];
    let broken: Vec<String> = orders
        .iter()
        .filter(|(first, then, _)| !runs_before(&schedule, first, then))
        .map(|(first, then, why)| format!("{first} is not ordered before {then} ({why})"))
        .collect();
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}
