//! A small coverage-guided fuzzing engine in the manner of libFuzzer and AFL, for stable
//! Rust: the target crates are built with LLVM's `SanitizerCoverage` (edge counters and
//! comparison hooks, see [`coverage`]); an input that reaches a new edge, or an edge a new
//! number of times (AFL's count buckets), joins the corpus; inputs are mutated by
//! [`mutate::havoc`]. A panic — even one the code under test catches itself, which
//! `panic = "abort"` would not allow — is a finding, its input kept (one per location); a
//! run longer than the time limit or an allocation over the memory limit stops the
//! process with the input saved ([`Guard`]), as libFuzzer's `-timeout` and
//! `-malloc_limit_mb` do.
//!
//! At the end the corpus is reduced to the smallest inputs that keep every edge reached
//! (as `afl-cmin`) and written back, so the committed corpus stays small and the
//! replay tests fast.

pub mod coverage;
pub mod mutate;

use crate::Target;
use coverage::Counters;
use mutate::Rng;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// What one fuzzing run does.
#[derive(Clone, Debug)]
pub struct Options {
    /// The target.
    pub target: Target,
    /// Stop after this long.
    pub duration: Duration,
    /// Stop after this many executions (`None`: only the time limit).
    pub max_runs: Option<u64>,
    /// Largest input, bytes.
    pub max_len: usize,
    /// The generator's seed (runs are reproducible from it).
    pub seed: u64,
    /// The corpus folder: read at the start, reduced and rewritten at the end.
    pub corpus: PathBuf,
    /// Where inputs that panic, hang or allocate too much are written.
    pub artifacts: PathBuf,
}

/// What a run found.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Target executions.
    pub runs: u64,
    /// Seconds the search ran.
    pub seconds: f64,
    /// Edges reached at least once.
    pub edges: usize,
    /// Instrumented edges in the target crates.
    pub instrumented: usize,
    /// Features (edge × count bucket) reached.
    pub features: usize,
    /// Corpus entries after reduction.
    pub corpus: usize,
    /// Inputs that panicked: (panic location and message, artifact).
    pub crashes: Vec<(String, PathBuf)>,
}

/// The input being run, for the watchdog and the memory guard to save.
static CURRENT: Mutex<Vec<u8>> = Mutex::new(Vec::new());
static ARTIFACTS: Mutex<Option<PathBuf>> = Mutex::new(None);
/// When the current run started, milliseconds since [`EPOCH`] (0: idle).
static STARTED: AtomicU64 = AtomicU64::new(0);
static EPOCH: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
/// Set while a guard saves an input: the memory limit stands aside meanwhile.
static SAVING: AtomicBool = AtomicBool::new(false);

/// The process-ending findings.
pub struct Guard;

impl Guard {
    /// Whether the memory limit applies now (not while an input is being saved).
    pub fn limit_applies() -> bool {
        !SAVING.load(Ordering::Relaxed)
    }

    /// An allocation of `bytes` went over the limit: saves the input as `oom-…`, says
    /// so and ends the process (exit code 4).
    pub fn out_of_memory(bytes: usize, limit_mb: usize) -> ! {
        SAVING.store(true, Ordering::Relaxed);
        let path = save_current("oom");
        eprintln!(
            "penumbra-fuzz: out of memory: an allocation of {bytes} bytes went over the \
             {limit_mb} MiB limit; input saved as {}",
            path.display()
        );
        std::process::exit(4);
    }

    /// Starts the watchdog: a run longer than `limit` saves its input as `timeout-…`
    /// and ends the process (exit code 3).
    pub fn watch(limit: Duration) {
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_millis(50));
                let started = STARTED.load(Ordering::Relaxed);
                if started != 0 && now_ms().saturating_sub(started) > limit.as_millis() as u64 {
                    SAVING.store(true, Ordering::Relaxed);
                    let path = save_current("timeout");
                    eprintln!(
                        "penumbra-fuzz: hang: one run took over {} s; input saved as {}",
                        limit.as_secs_f32(),
                        path.display()
                    );
                    std::process::exit(3);
                }
            }
        });
    }
}

fn now_ms() -> u64 {
    EPOCH.get_or_init(Instant::now).elapsed().as_millis() as u64 + 1
}

fn save_current(kind: &str) -> PathBuf {
    let data = CURRENT.lock().map(|d| d.clone()).unwrap_or_default();
    let dir = ARTIFACTS
        .lock()
        .ok()
        .and_then(|a| a.clone())
        .unwrap_or_else(|| PathBuf::from("."));
    let path = dir.join(format!("{kind}-{:016x}", hash(&data)));
    let _ = std::fs::create_dir_all(&dir);
    let _ = std::fs::write(&path, &data);
    path
}

/// FNV-1a: names corpus files by their content.
pub fn hash(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// AFL's count buckets: 1, 2, 3, 4–7, 8–15, 16–31, 32–127, 128+.
fn bucket(count: u8) -> u8 {
    match count {
        0 => 0,
        1 => 1,
        2 => 2,
        3 => 4,
        4..=7 => 8,
        8..=15 => 16,
        16..=31 => 32,
        32..=127 => 64,
        _ => 128,
    }
}

struct Entry {
    data: Vec<u8>,
    /// (edge, bucket) pairs the input reaches.
    features: Vec<(u32, u8)>,
}

/// The outcome of one execution.
enum Outcome {
    Fine,
    Panicked(String),
}

fn execute(target: Target, counters: &Counters, data: &[u8]) -> Outcome {
    PANICKED.store(false, Ordering::Relaxed);
    if let Ok(mut current) = CURRENT.lock() {
        current.clear();
        current.extend_from_slice(data);
    }
    counters.clear();
    coverage::record_comparisons(true);
    STARTED.store(now_ms(), Ordering::Relaxed);
    let result = std::panic::catch_unwind(|| target.run(data));
    STARTED.store(0, Ordering::Relaxed);
    coverage::record_comparisons(false);
    // A panic that the code under test caught itself counts too: under
    // `panic = "abort"` it would have ended the app.
    if result.is_err() || PANICKED.load(Ordering::Relaxed) {
        Outcome::Panicked(LAST_PANIC.lock().map(|p| p.clone()).unwrap_or_default())
    } else {
        Outcome::Fine
    }
}

static LAST_PANIC: Mutex<String> = Mutex::new(String::new());
/// Set by the panic hook: any panic during a run, caught or not.
static PANICKED: AtomicBool = AtomicBool::new(false);

/// Runs the search. Fails only when the binary has no coverage instrumentation.
pub fn fuzz(options: &Options) -> Result<Report, String> {
    let counters = Counters::get();
    if counters.is_empty() {
        return Err("no coverage instrumentation: build with `cargo xtask fuzz`".into());
    }
    let _ = now_ms();
    if let Ok(mut a) = ARTIFACTS.lock() {
        *a = Some(options.artifacts.clone());
    }
    std::panic::set_hook(Box::new(|info| {
        let location = info
            .location()
            .map(|l| format!("{}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = format!("{location}: {message}");
        }
        PANICKED.store(true, Ordering::Relaxed);
    }));

    let target = options.target;
    let start = Instant::now();
    let mut rng = Rng::new(options.seed);
    let mut seen = vec![0u8; counters.len()];
    let mut corpus: Vec<Entry> = Vec::new();
    let mut report = Report {
        instrumented: counters.len(),
        ..Report::default()
    };
    let mut crash_sites: HashSet<String> = HashSet::new();
    let mut hits: Vec<(u32, u8)> = Vec::new();

    let mut consider = |data: &[u8], report: &mut Report, corpus: &mut Vec<Entry>, force: bool| {
        report.runs += 1;
        match execute(target, &counters, data) {
            Outcome::Panicked(site) => {
                let key = site.split(": ").next().unwrap_or("").to_string();
                if crash_sites.insert(key) {
                    let _ = std::fs::create_dir_all(&options.artifacts);
                    let path = options.artifacts.join(format!("crash-{:016x}", hash(data)));
                    let _ = std::fs::write(&path, data);
                    eprintln!(
                        "penumbra-fuzz: panic at {site}; input saved as {}",
                        path.display()
                    );
                    report.crashes.push((site, path));
                }
            }
            Outcome::Fine => {
                hits.clear();
                let mut new = false;
                counters.for_each_hit(|edge, count| {
                    let b = bucket(count);
                    hits.push((edge as u32, b));
                    if seen[edge] & b == 0 {
                        new = true;
                    }
                });
                if new || force {
                    for &(edge, b) in &hits {
                        seen[edge as usize] |= b;
                    }
                    corpus.push(Entry {
                        data: data.to_vec(),
                        features: hits.clone(),
                    });
                }
            }
        }
    };

    for data in target
        .seeds()
        .into_iter()
        .chain(read_corpus(&options.corpus))
    {
        consider(&data, &mut report, &mut corpus, false);
    }
    if corpus.is_empty() {
        // Every seed panicked: search from an empty input.
        consider(&[], &mut report, &mut corpus, true);
    }
    let dictionary = target.dictionary();
    let text = matches!(target, Target::Obj | Target::Gltf | Target::Hair);
    let mut input = Vec::new();
    while start.elapsed() < options.duration && options.max_runs.is_none_or(|m| report.runs < m) {
        // Newer entries (found later, usually deeper) a little more often.
        let n = corpus.len();
        let pick = if rng.one_in(2) {
            n - 1 - rng.below(n.min(16))
        } else {
            rng.below(n)
        };
        input.clear();
        input.extend_from_slice(&corpus[pick].data);
        let other = rng.below(n);
        mutate::havoc(
            &mut rng,
            &mut input,
            options.max_len,
            dictionary,
            &corpus[other].data,
            text,
        );
        consider(&input, &mut report, &mut corpus, false);
    }
    report.seconds = start.elapsed().as_secs_f64();
    report.edges = seen.iter().filter(|&&b| b != 0).count();
    report.features = seen.iter().map(|b| b.count_ones() as usize).sum();
    let kept = reduce(&corpus);
    report.corpus = kept.len();
    write_corpus(&options.corpus, &kept)
        .map_err(|e| format!("writing {}: {e}", options.corpus.display()))?;
    Ok(report)
}

/// The smallest entries that together reach every edge reached (`afl-cmin`'s rule on
/// edges rather than count buckets: the committed corpus stays a few hundred files; a
/// later search finds the buckets again in seconds).
fn reduce(corpus: &[Entry]) -> Vec<&[u8]> {
    let mut order: Vec<&Entry> = corpus.iter().collect();
    order.sort_by_key(|e| (e.data.len(), hash(&e.data)));
    let mut covered: HashSet<u32> = HashSet::new();
    let mut kept = Vec::new();
    for entry in order {
        if entry
            .features
            .iter()
            .any(|(edge, _)| !covered.contains(edge))
        {
            covered.extend(entry.features.iter().map(|(edge, _)| *edge));
            kept.push(&entry.data[..]);
        }
    }
    kept
}

/// The files of a corpus folder, in name order (none when it does not exist).
pub fn read_corpus(dir: &Path) -> Vec<Vec<u8>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    paths.sort();
    paths.iter().filter_map(|p| std::fs::read(p).ok()).collect()
}

fn write_corpus(dir: &Path, kept: &[&[u8]]) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let names: HashSet<String> = kept.iter().map(|d| format!("{:016x}", hash(d))).collect();
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or("")
            .to_string();
        if path.is_file() && !names.contains(&name) {
            std::fs::remove_file(&path)?;
        }
    }
    for data in kept {
        let path = dir.join(format!("{:016x}", hash(data)));
        if !path.exists() {
            std::fs::write(path, data)?;
        }
    }
    Ok(())
}
