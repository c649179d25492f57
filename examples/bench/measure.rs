//! What the benchmark measures in each run, and how.
//!
//! - **GPU time per pass**: Bevy's render diagnostics (`RenderDiagnosticsPlugin`: GPU
//!   timestamp queries around every pass that records a span, Bevy's and Penumbra's).
//!   Spans of one name closed several times in a frame (Bevy's mesh preprocessing, once
//!   per view) are summed per frame.
//! - **The frame's GPU time**: two timestamps of the benchmark's own, the first submitted
//!   just before the render graph submits the frame's command buffers (after they are
//!   all encoded: a timestamp submitted earlier would also count the GPU idling while the
//!   CPU encodes, which on a real GPU is most of a frame), the last after Bevy's
//!   `render_system`, so uninstrumented work (Bevy's shadow maps, depth of field,
//!   deferred lighting, copies) counts too. (Bevy's spans cannot hold it: they nest per
//!   thread, and the render graph's systems run on several.) Work a system submits
//!   itself during the render graph (rare: a grown buffer's copy) falls before it.
//! - **Segments of the frame**: four timestamps more, written into the command stream
//!   between Bevy's passes (`mark::<I>` systems in `Core3d`), cut the frame's GPU time
//!   into [`SEGMENTS`] — what falls outside every pass span (Bevy's shadow maps and
//!   deferred lighting, MSAA resolves, copies) lands in one of them. The first two
//!   meet where Penumbra's and Bevy's lighting passes start; work Bevy leaves unordered
//!   against them (the face-normal prepass, say) may fall on either side.
//! - **CPU time**: the wall time of each `App::update` (main world and, pipelined, the
//!   render world of the previous frame), the CPU time Bevy's diagnostics record for
//!   encoding each pass (`elapsed_cpu`), and each Penumbra system's own run time
//!   (`bevy_penumbra_df::system_times`), summed over what ran during each update (with
//!   pipelined rendering, the render world's systems of the frame before).
//! - **Frames in flight**: at most two (`FRAMES_IN_FLIGHT`): after each frame the
//!   render world waits for the GPU to finish the frame two before it, as a swap chain
//!   would; a headless app otherwise queues frames without limit. Each run drains the
//!   GPU before its app is dropped.
//! - **GPU memory**: the device allocator's report (wgpu's `generate_allocator_report`),
//!   summing the allocations whose label starts with `penumbra` (every Penumbra
//!   resource's label does) against all allocations.

use bevy::core_pipeline::core_3d::{main_opaque_pass_3d, main_transparent_pass_3d};
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::diagnostic::DiagnosticsStore;
use bevy::pbr::deferred::deferred_lighting;
use bevy::prelude::*;
use bevy::render::renderer::{
    RenderContext, RenderDevice, RenderGraph, RenderGraphSystems, RenderQueue, render_system,
};
use bevy::render::{Render, RenderApp, RenderSystems};
use bevy_penumbra_df::lighting::PenumbraLightingSystems;
use bevy_penumbra_df::system_times;
use penumbra_test::wgpu::{
    Buffer, BufferDescriptor, BufferUsages, Features as WgpuFeatures, MapMode, PollType, QuerySet,
    QuerySetDescriptor, QueryType, SubmissionIndex,
};
use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Median, 95th percentile and mean of a series of samples (milliseconds or bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// The median.
    pub median: f64,
    /// The 95th percentile (nearest rank).
    pub p95: f64,
    /// The mean.
    pub mean: f64,
    /// How many samples.
    pub n: usize,
}

impl Stats {
    /// The statistics of `samples`; `None` when there are none.
    pub fn of(samples: &[f64]) -> Option<Stats> {
        let mut s: Vec<f64> = samples.iter().copied().filter(|v| v.is_finite()).collect();
        if s.is_empty() {
            return None;
        }
        s.sort_by(f64::total_cmp);
        let rank = |q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
        let median = if s.len() % 2 == 1 {
            s[s.len() / 2]
        } else {
            0.5 * (s[s.len() / 2 - 1] + s[s.len() / 2])
        };
        Some(Stats {
            median,
            p95: rank(0.95),
            mean: s.iter().sum::<f64>() / s.len() as f64,
            n: s.len(),
        })
    }
}

/// Per-frame samples of every render diagnostic, collected while `recording`.
#[derive(Resource, Default)]
pub struct Samples {
    /// Whether frames are being measured.
    pub recording: bool,
    /// Per diagnostic path (`render/<span>/elapsed_gpu` …), one summed value per frame.
    pub series: BTreeMap<String, Vec<f64>>,
    /// The newest measurement already taken, per path.
    seen: HashMap<String, Instant>,
}

/// Takes each render diagnostic's new measurements of this frame (summed per path).
pub fn collect_samples(store: Res<DiagnosticsStore>, mut samples: ResMut<Samples>) {
    let samples = &mut *samples;
    for diagnostic in store.iter() {
        let path = diagnostic.path().as_str();
        if !path.starts_with("render/") {
            continue;
        }
        let last = samples.seen.get(path).copied();
        let mut newest = last;
        let mut sum = None::<f64>;
        for m in diagnostic.measurements() {
            if last.is_none_or(|t| m.time > t) {
                *sum.get_or_insert(0.0) += m.value;
                newest = Some(newest.map_or(m.time, |t: Instant| t.max(m.time)));
            }
        }
        if let Some(t) = newest {
            samples.seen.insert(path.to_owned(), t);
        }
        if let (true, Some(v)) = (samples.recording, sum) {
            samples.series.entry(path.to_owned()).or_default().push(v);
        }
    }
}

/// Each Penumbra system's CPU time per measured update (`system_times`).
pub struct SystemSeries {
    frames: usize,
    series: BTreeMap<&'static str, Vec<f64>>,
    totals: Vec<f64>,
}

impl SystemSeries {
    /// Starts recording (what ran before is dropped).
    pub fn start() -> Self {
        system_times::record_system_times(true);
        system_times::take_system_times();
        Self {
            frames: 0,
            series: BTreeMap::new(),
            totals: Vec::new(),
        }
    }

    /// Takes what ran since the last call as one frame's (systems that did not run: 0).
    pub fn take_frame(&mut self) {
        let times = system_times::take_system_times();
        let mut total = 0.0;
        for (name, time, _) in times {
            let ms = time.as_secs_f64() * 1e3;
            total += ms;
            let series = self.series.entry(name).or_default();
            series.resize(self.frames, 0.0);
            series.push(ms);
        }
        self.frames += 1;
        self.totals.push(total);
    }

    /// Stops recording: the total's statistics and each system's, by name.
    pub fn finish(mut self) -> (Option<Stats>, Vec<(String, Stats)>) {
        system_times::record_system_times(false);
        let systems = std::mem::take(&mut self.series)
            .into_iter()
            .filter_map(|(name, mut v)| {
                v.resize(self.frames, 0.0);
                Some((name.to_owned(), Stats::of(&v)?))
            })
            .collect();
        (Stats::of(&self.totals), systems)
    }
}

/// GPU memory held when asked: Penumbra's allocations and all of them, bytes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Memory {
    /// Bytes in allocations labelled `penumbra…`.
    pub penumbra_bytes: u64,
    /// Their count.
    pub penumbra_allocations: u64,
    /// Bytes in all allocations.
    pub total_bytes: u64,
}

/// Shared by the main and the render world: a request and its answer.
#[derive(Resource, Clone, Default)]
pub struct MemoryProbe(pub Arc<Mutex<(bool, Option<Memory>)>>);

impl MemoryProbe {
    /// Asks the render world for a report (answered within a frame or two).
    pub fn request(&self) {
        self.0.lock().expect("not poisoned").0 = true;
    }
    /// The answer, once there.
    pub fn take(&self) -> Option<Memory> {
        self.0.lock().expect("not poisoned").1.take()
    }
}

fn answer_memory_probe(probe: Res<MemoryProbe>, device: Res<RenderDevice>) {
    let mut state = probe.0.lock().expect("not poisoned");
    if !state.0 {
        return;
    }
    state.0 = false;
    let Some(report) = device.wgpu_device().generate_allocator_report() else {
        state.1 = Some(Memory::default());
        return;
    };
    let mut memory = Memory {
        total_bytes: report.total_allocated_bytes,
        ..default()
    };
    for a in report
        .allocations
        .iter()
        .filter(|a| a.name.starts_with("penumbra"))
    {
        memory.penumbra_bytes += a.size;
        memory.penumbra_allocations += 1;
    }
    state.1 = Some(memory);
}

/// Each frame's GPU time, ms, as the frame timer reads it back, and its
/// [`SEGMENTS`] (shared by both worlds; empty when the device has no timestamps inside
/// encoders).
#[derive(Resource, Clone, Default)]
pub struct FrameGpuTimes(
    pub Arc<Mutex<Vec<f64>>>,
    pub Arc<Mutex<Vec<[f64; SEGMENTS.len()]>>>,
);

/// The parts the marks cut a frame's GPU time into, in order.
pub const SEGMENTS: [&str; MARKS as usize + 1] = [
    "before the main pass (prepasses, shadow maps)",
    "main pass up to the opaque pass (deferred lighting; Penumbra's DF shadows, DFAO)",
    "main opaque pass with its MSAA resolve",
    "main transparent pass",
    "post-processing and upscaling",
];

/// Timestamps written between Bevy's passes each frame.
const MARKS: u32 = 4;

/// The frame timer: two timestamps a frame, resolved into a ring of read-back buffers.
#[derive(Resource)]
struct FrameTimer {
    set: QuerySet,
    resolve: Buffer,
    ring: Vec<(Buffer, Arc<AtomicBool>, bool)>,
    next: usize,
    period_ns: f64,
    /// Whether this frame's begin was written.
    open: bool,
}

const RING: usize = 8;

fn init_frame_timer(mut commands: Commands, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
    let needed = WgpuFeatures::TIMESTAMP_QUERY | WgpuFeatures::TIMESTAMP_QUERY_INSIDE_ENCODERS;
    if !device.features().contains(needed) {
        warn!("penumbra-bench: no timestamps inside encoders: no frame GPU time");
        return;
    }
    let wgpu = device.wgpu_device();
    let buffer = |label, usage| {
        wgpu.create_buffer(&BufferDescriptor {
            label: Some(label),
            size: 8 * u64::from(2 + MARKS),
            usage,
            mapped_at_creation: false,
        })
    };
    commands.insert_resource(FrameTimer {
        set: wgpu.create_query_set(&QuerySetDescriptor {
            label: Some("bench_frame_timestamps"),
            ty: QueryType::Timestamp,
            count: 2 + MARKS,
        }),
        resolve: buffer(
            "bench_frame_resolve",
            BufferUsages::QUERY_RESOLVE | BufferUsages::COPY_SRC,
        ),
        ring: (0..RING)
            .map(|_| {
                let b = buffer(
                    "bench_frame_read",
                    BufferUsages::COPY_DST | BufferUsages::MAP_READ,
                );
                (b, Arc::new(AtomicBool::new(false)), false)
            })
            .collect(),
        next: 0,
        period_ns: f64::from(queue.get_timestamp_period()),
        open: false,
    });
}

/// Reads the frames whose timestamps arrived and claims this frame's read-back buffer.
fn begin_frame_timer(timer: Option<ResMut<FrameTimer>>, times: Res<FrameGpuTimes>) {
    let Some(mut timer) = timer else {
        return;
    };
    let period = timer.period_ns;
    for (buffer, mapped, in_flight) in &mut timer.ring {
        if *in_flight && mapped.load(Ordering::Acquire) {
            let ticks: Vec<u64> = buffer
                .slice(..)
                .get_mapped_range()
                .chunks_exact(8)
                .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect();
            buffer.unmap();
            mapped.store(false, Ordering::Release);
            *in_flight = false;
            let ms = |from: u64, to: u64| (to - from) as f64 * period * 1e-6;
            if ticks[1] > ticks[0] {
                times
                    .0
                    .lock()
                    .expect("not poisoned")
                    .push(ms(ticks[0], ticks[1]));
            }
            // Start, the marks, end: in order only when every mark was written this
            // frame (an unwritten one reads 0 or an older frame's).
            let mut order = vec![ticks[0]];
            order.extend(&ticks[2..]);
            order.push(ticks[1]);
            if order.windows(2).all(|w| w[0] <= w[1]) {
                let segments = std::array::from_fn(|k| ms(order[k], order[k + 1]));
                times.1.lock().expect("not poisoned").push(segments);
            }
        }
    }
    let i = timer.next;
    timer.open = !timer.ring[i].2;
}

/// Submits this frame's first timestamp: in the render graph, after every pass is
/// encoded and just before Bevy submits them, so the GPU reaches it when the frame's
/// work is about to start, not while the CPU still encodes.
fn stamp_frame_start(
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    timer: Option<Res<FrameTimer>>,
) {
    let Some(timer) = timer.filter(|t| t.open) else {
        return;
    };
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.write_timestamp(&timer.set, 0);
    queue.submit([encoder.finish()]);
}

/// Submits this frame's last timestamp (after the render graph's last submission) and
/// sends both to the next free read-back buffer.
fn end_frame_timer(
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    timer: Option<ResMut<FrameTimer>>,
) {
    let Some(mut timer) = timer else {
        return;
    };
    if !timer.open {
        return; // the ring is full (read-backs late): this frame is not timed
    }
    let timer = &mut *timer;
    let i = timer.next;
    let (buffer, mapped, in_flight) = &mut timer.ring[i];
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.write_timestamp(&timer.set, 1);
    encoder.resolve_query_set(&timer.set, 0..2 + MARKS, &timer.resolve, 0);
    encoder.copy_buffer_to_buffer(&timer.resolve, 0, buffer, 0, 8 * u64::from(2 + MARKS));
    let flag = mapped.clone();
    encoder.map_buffer_on_submit(buffer, MapMode::Read, .., move |result| {
        if result.is_ok() {
            flag.store(true, Ordering::Release);
        }
    });
    queue.submit([encoder.finish()]);
    *in_flight = true;
    timer.next = (i + 1) % RING;
}

/// Mark `I`: a timestamp in the command stream where this system runs in `Core3d`.
fn mark<const I: u32>(timer: Option<Res<FrameTimer>>, mut ctx: RenderContext) {
    if let Some(timer) = timer.filter(|t| t.open) {
        ctx.command_encoder().write_timestamp(&timer.set, 2 + I);
    }
}

/// Frames the GPU may lag behind the CPU. A headless app presents nothing, so nothing
/// else holds the CPU back: without this it queues frames far ahead of a slow GPU,
/// and dropping the app then waits on all of them (wgpu gives up after 6.3 s and
/// panics). Two, as a swap chain's usual latency.
const FRAMES_IN_FLIGHT: usize = 2;

/// The submissions of the frames in flight, oldest first.
#[derive(Resource, Default)]
struct InFlight(std::collections::VecDeque<SubmissionIndex>);

/// Marks the end of this frame's work with a submission and waits until the GPU has
/// finished the frame [`FRAMES_IN_FLIGHT`] before it.
fn throttle_frames(
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut in_flight: ResMut<InFlight>,
) {
    let encoder = device.create_command_encoder(&Default::default());
    in_flight.0.push_back(queue.submit([encoder.finish()]));
    while in_flight.0.len() > FRAMES_IN_FLIGHT {
        let oldest = in_flight.0.pop_front().expect("not empty");
        // An error here (a lost device) shows again, with its cause, where Bevy polls.
        let _ = device.wgpu_device().poll(PollType::Wait {
            submission_index: Some(oldest),
            timeout: None,
        });
    }
}

/// Waits until the GPU has finished everything submitted, so that dropping the app
/// does not wait (and give up) on queued frames.
pub fn drain_gpu(app: &App) {
    if let Some(render_app) = app.get_sub_app(RenderApp)
        && let Some(device) = render_app.world().get_resource::<RenderDevice>()
    {
        let _ = device.wgpu_device().poll(PollType::wait_indefinitely());
    }
}

/// Adds the frame timer, the memory probe and the sample collection to `app` (after
/// Bevy's `DefaultPlugins` and `RenderDiagnosticsPlugin`).
pub fn add_measurement(app: &mut App) {
    let probe = MemoryProbe::default();
    let times = FrameGpuTimes::default();
    app.init_resource::<Samples>()
        .insert_resource(probe.clone())
        .insert_resource(times.clone())
        .add_systems(Last, collect_samples);
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app
            .insert_resource(probe)
            .insert_resource(times)
            .init_resource::<InFlight>()
            .add_systems(bevy::render::RenderStartup, init_frame_timer)
            .add_systems(
                Core3d,
                (
                    mark::<0>
                        .before(deferred_lighting)
                        .before(PenumbraLightingSystems::Inputs),
                    mark::<1>
                        .after(deferred_lighting)
                        .after(PenumbraLightingSystems::Lighting)
                        .before(main_opaque_pass_3d),
                    mark::<2>
                        .after(main_opaque_pass_3d)
                        .before(main_transparent_pass_3d),
                    mark::<3>.after(main_transparent_pass_3d),
                )
                    .in_set(Core3dSystems::MainPass),
            )
            .add_systems(
                RenderGraph,
                stamp_frame_start
                    .after(RenderGraphSystems::Render)
                    .before(RenderGraphSystems::Submit),
            )
            .add_systems(
                Render,
                (
                    begin_frame_timer
                        .in_set(RenderSystems::Render)
                        .before(render_system),
                    (end_frame_timer, throttle_frames)
                        .chain()
                        .in_set(RenderSystems::Render)
                        .after(render_system),
                    answer_memory_probe.in_set(RenderSystems::Cleanup),
                ),
            );
    }
}

#[cfg(test)]
mod tests {
    use super::Stats;

    #[test]
    fn stats_by_nearest_rank() {
        let s = Stats::of(&[5.0, 1.0, 3.0, 2.0, 4.0]).unwrap();
        assert_eq!((s.median, s.p95, s.mean, s.n), (3.0, 5.0, 3.0, 5));
        let s = Stats::of(&(1..=100).map(f64::from).collect::<Vec<_>>()).unwrap();
        assert_eq!((s.median, s.p95), (50.5, 95.0));
        assert!(Stats::of(&[f64::NAN]).is_none());
    }
}
