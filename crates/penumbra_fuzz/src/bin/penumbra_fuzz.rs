//! `penumbra-fuzz`: runs the coverage-guided search on one target. Build it with
//! `cargo xtask fuzz` (which adds the coverage instrumentation); run alone it says so.
// The memory limit is a global allocator: `unsafe` by nature, confined to `Limited`.
#![allow(unsafe_code)]

use clap::Parser;
use penumbra_fuzz::Target;
use penumbra_fuzz::engine::{self, Guard, Options};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// Counts live heap bytes and ends the run when they pass the limit.
struct Limited;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);

// SAFETY: every call is forwarded to `System` with the caller's layout; the counting
// around it does not touch the memory.
unsafe impl GlobalAlloc for Limited {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        check(layout.size());
        // SAFETY: forwarded as received.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        check(layout.size());
        // SAFETY: forwarded as received.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: forwarded as received.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        check(new_size);
        // SAFETY: forwarded as received.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

fn check(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    let limit = LIMIT.load(Ordering::Relaxed);
    if live > limit && Guard::limit_applies() {
        Guard::out_of_memory(bytes, limit >> 20);
    }
}

#[global_allocator]
static ALLOCATOR: Limited = Limited;

/// Coverage-guided fuzzing of one of Penumbra's input formats.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Args {
    /// The target to fuzz.
    #[arg(value_enum)]
    target: Target,
    /// How long to search, seconds.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Stop after this many executions (default: only the time limit).
    #[arg(long)]
    runs: Option<u64>,
    /// Largest input, bytes.
    #[arg(long, default_value_t = 8192)]
    max_len: usize,
    /// The mutator's seed (a run is reproducible from it and the corpus).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Heap limit, MiB: going over it is a finding (libFuzzer's `-malloc_limit_mb`).
    #[arg(long, default_value_t = 2048)]
    memory_mb: usize,
    /// One execution longer than this, seconds, is a hang.
    #[arg(long, default_value_t = 5.0)]
    timeout: f64,
    /// Corpus folder (default: the committed `corpus/<target>`).
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// Where failing inputs go (default: `artifacts/<target>`, not committed).
    #[arg(long)]
    artifacts: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let name = args.target.name();
    let options = Options {
        target: args.target,
        duration: Duration::from_secs_f64(args.seconds.max(0.0)),
        max_runs: args.runs,
        max_len: args.max_len,
        seed: args.seed,
        corpus: args
            .corpus
            .unwrap_or_else(|| penumbra_fuzz::crate_dir().join("corpus").join(name)),
        artifacts: args
            .artifacts
            .unwrap_or_else(|| penumbra_fuzz::crate_dir().join("artifacts").join(name)),
    };
    LIMIT.store(args.memory_mb << 20, Ordering::Relaxed);
    Guard::watch(Duration::from_secs_f64(args.timeout.max(0.01)));
    match engine::fuzz(&options) {
        Ok(report) => {
            println!(
                "{{\"target\":\"{name}\",\"runs\":{},\"seconds\":{:.1},\"runs_per_second\":{:.0},\
                 \"edges\":{},\"instrumented_edges\":{},\"features\":{},\"corpus\":{},\"crashes\":{}}}",
                report.runs,
                report.seconds,
                report.runs as f64 / report.seconds.max(1e-9),
                report.edges,
                report.instrumented,
                report.features,
                report.corpus,
                report.crashes.len()
            );
            for (site, path) in &report.crashes {
                eprintln!("crash: {site} ({})", path.display());
            }
            if report.crashes.is_empty() {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(2)
            }
        }
        Err(e) => {
            eprintln!("penumbra-fuzz: {e}");
            ExitCode::FAILURE
        }
    }
}
