//! The CPU time of Penumbra's own systems, per system, without Bevy's `trace` feature.
//!
//! Every system Penumbra schedules runs through [`timed`], an `AdapterSystem` that, while
//! recording is on ([`record_system_times`]), adds each run's wall time to its system's
//! total; [`take_system_times`] returns the totals since the last call and starts new
//! ones (a benchmark takes them once per frame: `penumbra-bench` reports them). Off (the
//! default), a run costs one relaxed atomic load more.
//!
//! The time is the system's own run on whichever thread ran it (Bevy runs systems in
//! parallel: the totals add up to CPU time, not to the frame's wall time). A system's
//! deferred commands are applied later, by Bevy, and are not counted.

use bevy::ecs::system::{Adapt, AdapterSystem, RunSystemError, SystemIn, SystemInput};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

static RECORDING: AtomicBool = AtomicBool::new(false);
static TOTALS: Mutex<Option<HashMap<&'static str, (Duration, u32)>>> = Mutex::new(None);

/// Turns recording on or off (process-wide; off by default).
pub fn record_system_times(on: bool) {
    RECORDING.store(on, Ordering::Relaxed);
}

/// Each recorded system's name (the function's), total run time and runs since the last
/// call, sorted by name; the totals start again from zero.
pub fn take_system_times() -> Vec<(&'static str, Duration, u32)> {
    let mut totals = TOTALS.lock().unwrap_or_else(|e| e.into_inner());
    let mut out: Vec<_> = totals
        .take()
        .unwrap_or_default()
        .into_iter()
        .map(|(name, (time, runs))| (name, time, runs))
        .collect();
    out.sort_by_key(|e| e.0);
    out
}

/// The adapter [`timed`] wraps a system in.
pub struct Timed {
    name: &'static str,
}

impl<S: System> Adapt<S> for Timed {
    type In = S::In;
    type Out = S::Out;

    fn adapt(
        &mut self,
        input: <Self::In as SystemInput>::Inner<'_>,
        run_system: impl FnOnce(SystemIn<'_, S>) -> Result<S::Out, RunSystemError>,
    ) -> Result<Self::Out, RunSystemError> {
        if !RECORDING.load(Ordering::Relaxed) {
            return run_system(input);
        }
        let start = Instant::now();
        let out = run_system(input);
        let elapsed = start.elapsed();
        let mut totals = TOTALS.lock().unwrap_or_else(|e| e.into_inner());
        let entry = totals
            .get_or_insert_with(HashMap::default)
            .entry(self.name)
            .or_default();
        entry.0 += elapsed;
        entry.1 += 1;
        out
    }
}

/// `system`, timed while recording is on (see the [module docs](self)). Orders, sets and
/// run conditions apply to it as to `system` (`.after(system)` still finds it).
pub fn timed<I, O, M, S>(system: S) -> AdapterSystem<Timed, S::System>
where
    I: SystemInput,
    S: IntoSystem<I, O, M>,
{
    let name = short_name(std::any::type_name::<S>());
    let system = IntoSystem::into_system(system);
    let debug_name = system.name();
    AdapterSystem::new(Timed { name }, system, debug_name)
}

/// A function's name without its path (`a::b::prepare_x` → `prepare_x`).
fn short_name(path: &'static str) -> &'static str {
    path.rsplit("::").next().unwrap_or(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn busy() {
        std::thread::sleep(Duration::from_millis(2));
    }

    fn idle() {}

    /// Runs are counted and timed while recording, not otherwise; ordering against the
    /// wrapped function still holds.
    #[test]
    fn timed_systems_are_measured_while_recording() {
        let mut app = App::new();
        app.add_systems(Update, (timed(busy), timed(idle).after(busy)));
        app.update();
        take_system_times();
        record_system_times(true);
        app.update();
        app.update();
        record_system_times(false);
        let times = take_system_times();
        let of = |name| times.iter().find(|t| t.0 == name).copied();
        let (_, busy_time, busy_runs) = of("busy").expect("busy recorded");
        assert_eq!(busy_runs, 2);
        assert!(busy_time >= Duration::from_millis(4), "{busy_time:?}");
        assert_eq!(of("idle").map(|t| t.2), Some(2));
        app.update();
        assert!(take_system_times().is_empty(), "off: nothing recorded");
    }
}
