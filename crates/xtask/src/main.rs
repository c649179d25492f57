//! Project tasks, run as `cargo xtask <task>` (an alias in `.cargo/config.toml`).
//!
//! - `cargo xtask showcase [ARGS]`: the main job — render the showcase scene (in a
//!   window when a display exists, else headless to a PNG whose path it prints).
//! - `cargo xtask bench-pack`: the GPU benchmark (`examples/penumbra_bench.rs`) built,
//!   stripped and packed with its scenes into one archive for a machine without Rust
//!   ([`bench_pack`]).
//! - `cargo xtask fuzz [--seconds N]`: coverage-guided fuzzing of every input format
//!   on stable Rust ([`fuzz`], `crates/penumbra_fuzz`).
//! - `cargo xtask test [ARGS]`: the whole test suite (`cargo test --workspace`), closing
//!   with a total in which tests that could not run here (no GPU adapter, no
//!   `../shared`: `penumbra_testkit::skip`) count as skipped, not passed.
//!
//! Both first make sure a Vulkan driver is installed (Penumbra renders through Vulkan;
//! on machines without a GPU that is Mesa's lavapipe, Debian package
//! `mesa-vulkan-drivers`). When it is missing and this runs as root with apt, it installs
//! the package; otherwise it stops at once, naming the package.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

mod bench_pack;
mod fuzz;

/// The workspace root: two levels above `CARGO_MANIFEST_DIR` as `cargo run` sets it for
/// this run (the clone being worked in), else as compiled in. A target directory shared
/// by several clones (`.ci/run`'s default, `~/.cache/penumbra/target`) may hold an xtask
/// binary that another clone built and cargo takes as fresh; its compiled-in path is
/// that clone's (`bench-pack` failed reading a clone that no longer existed).
pub(crate) fn workspace_root() -> Result<PathBuf, String> {
    let manifest = std::env::var_os("CARGO_MANIFEST_DIR")
        .map_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")), PathBuf::from);
    let root = manifest.join("../..");
    root.canonicalize()
        .map_err(|e| format!("{}: {e}", root.display()))
}

/// The Debian package providing lavapipe (it depends on the Vulkan loader, `libvulkan1`).
const DRIVER_PACKAGE: &str = "mesa-vulkan-drivers";

const USAGE: &str = "usage: cargo xtask <showcase|test|bench-pack|fuzz> [ARGS...]
  bench-pack       build examples/penumbra_bench.rs, strip it, pack it with its scenes
                   (target/bench-pack/penumbra-bench.tar.gz, at most 60 MiB)
  fuzz [--seconds N] [--target T]... [--jobs J] [--seed S]
                   coverage-guided fuzzing of the input formats (crates/penumbra_fuzz),
                   N seconds per target (default 60), J targets at a time (default 1)
  showcase [ARGS]  run examples/showcase.rs (ARGS go to the example: --headless --frames N --out PATH --size WxH)
  test [ARGS]      run the whole test suite: cargo test --workspace [ARGS]
                   (one test at a time per binary: RUST_TEST_THREADS=1 unless set)";

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let task = args.next();
    let rest: Vec<String> = args.collect();
    if task.as_deref() == Some("bench-pack") {
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        return match bench_pack::bench_pack(&cargo, &rest) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("xtask: bench-pack: {e}");
                ExitCode::FAILURE
            }
        };
    }
    if task.as_deref() == Some("fuzz") {
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        return match fuzz::fuzz(&cargo, &rest) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("xtask: fuzz: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let cargo_args: Vec<String> = match task.as_deref() {
        Some("test") => ["test", "--workspace"]
            .into_iter()
            .map(String::from)
            .chain(rest)
            .collect(),
        Some("showcase") => ["run", "--example", "showcase", "--"]
            .into_iter()
            .map(String::from)
            .chain(rest)
            .collect(),
        _ => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = ensure_vulkan_driver() {
        eprintln!("xtask: {e}");
        return ExitCode::FAILURE;
    }
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let command = || {
        let mut command = Command::new(&cargo);
        command.args(&cargo_args);
        // One test at a time per test binary: the GPU tests share two cores anyway, and
        // one Bevy app renders at a time per process (the harness's lock) regardless.
        // Override with RUST_TEST_THREADS.
        if task.as_deref() == Some("test") && std::env::var_os("RUST_TEST_THREADS").is_none() {
            command.env("RUST_TEST_THREADS", "1");
        }
        command
    };
    let result = if task.as_deref() == Some("test") {
        // Tests that cannot run here (no GPU adapter, no ../shared) record themselves
        // in this file: they count as skipped, not passed.
        let skip_log =
            std::env::temp_dir().join(format!("penumbra_skips_{}.log", std::process::id()));
        let _ = std::fs::remove_file(&skip_log);
        let mut test_command = command();
        test_command.env(penumbra_testkit::SKIP_LOG_ENV, &skip_log);
        match run_tests(test_command, &skip_log) {
            // A test binary died (a signal: no test reported failing). Not retried: the
            // one such crash seen so far was a real bug (a shader reading uninitialized
            // workgroup memory), found only once it was looked at.
            Ok((status, totals)) if !status.success() && totals.failed == 0 => {
                println!(
                    "xtask: a test process crashed without a failing test (see above: \
                     the last test it started, and the signal)"
                );
                Ok(status)
            }
            other => other.map(|(status, _)| status),
        }
    } else {
        command().status().map_err(|e| e.to_string())
    };
    match result {
        Ok(status) if status.success() => ExitCode::SUCCESS,
        Ok(status) => ExitCode::from(status.code().map_or(1, |c| c.clamp(1, 255) as u8)),
        Err(e) => {
            eprintln!("xtask: could not run cargo: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs `cargo test`, passing its output through, and closes with one line totalling
/// every `test result:` line (cargo prints one per test binary, the last often a
/// doc-test run of 0 tests); tests that recorded a skip in `skip_log` count as skipped,
/// not passed, and are listed.
fn run_tests(
    mut command: Command,
    skip_log: &Path,
) -> Result<(std::process::ExitStatus, Totals), String> {
    use std::io::{BufRead, BufReader, Write};
    let mut child = command
        .stdout(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    let stdout = child.stdout.take().expect("piped stdout");
    let mut totals = Totals::default();
    let mut out = std::io::stdout().lock();
    for line in BufReader::new(stdout).lines() {
        let line = line.map_err(|e| e.to_string())?;
        totals.add_line(&line);
        writeln!(out, "{line}").ok();
        out.flush().ok();
    }
    let status = child.wait().map_err(|e| e.to_string())?;
    let skipped: Vec<String> = std::fs::read_to_string(skip_log)
        .unwrap_or_default()
        .lines()
        .map(|l| l.replace('\t', ": "))
        .collect();
    let _ = std::fs::remove_file(skip_log);
    totals.skip_at_run_time(skipped.len() as u64);
    for line in &skipped {
        writeln!(out, "skipped at run time: {line}").ok();
    }
    writeln!(out, "{}", totals.summary()).ok();
    Ok((status, totals))
}

/// Sums of cargo test's `test result:` lines, and the tests that skipped at run time.
#[derive(Debug, Default, PartialEq)]
struct Totals {
    passed: u64,
    failed: u64,
    ignored: u64,
    /// Tests that returned early because they could not run here (cargo counts them as
    /// passed).
    skipped_at_run_time: u64,
}

impl Totals {
    /// Moves `n` tests that reported a skip from passed to skipped.
    fn skip_at_run_time(&mut self, n: u64) {
        let n = n.min(self.passed);
        self.passed -= n;
        self.skipped_at_run_time += n;
    }

    /// The closing line: `total: P passed, F failed, S skipped (I #[ignore]d, R at run
    /// time)`.
    fn summary(&self) -> String {
        format!(
            "total: {} passed, {} failed, {} skipped ({} #[ignore]d, {} at run time)",
            self.passed,
            self.failed,
            self.ignored + self.skipped_at_run_time,
            self.ignored,
            self.skipped_at_run_time
        )
    }

    /// Adds a line like `test result: ok. 8 passed; 0 failed; 1 ignored; 0 measured; …`.
    fn add_line(&mut self, line: &str) {
        let Some(rest) = line.trim().strip_prefix("test result: ") else {
            return;
        };
        for part in rest.split(';') {
            let mut words = part.split_whitespace().rev();
            let (Some(label), Some(count)) = (words.next(), words.next()) else {
                continue;
            };
            let Ok(n) = count.parse::<u64>() else {
                continue;
            };
            match label {
                "passed" => self.passed += n,
                "failed" => self.failed += n,
                "ignored" => self.ignored += n,
                _ => {}
            }
        }
    }
}

/// Directories where the Vulkan loader looks for installable client drivers (ICDs).
const ICD_DIRS: &[&str] = &[
    "/usr/share/vulkan/icd.d",
    "/usr/local/share/vulkan/icd.d",
    "/etc/vulkan/icd.d",
];

/// Where Debian-like and other distributions keep `libvulkan.so.1`.
const LOADER_PATHS: &[&str] = &[
    "/usr/lib/x86_64-linux-gnu/libvulkan.so.1",
    "/lib/x86_64-linux-gnu/libvulkan.so.1",
    "/usr/lib/aarch64-linux-gnu/libvulkan.so.1",
    "/lib/aarch64-linux-gnu/libvulkan.so.1",
    "/usr/lib64/libvulkan.so.1",
    "/usr/lib/libvulkan.so.1",
];

/// What is missing for Vulkan, if anything (Linux only; elsewhere the OS provides it).
fn missing_vulkan_parts() -> Vec<&'static str> {
    if !cfg!(target_os = "linux") {
        return Vec::new();
    }
    let mut missing = Vec::new();
    if !LOADER_PATHS.iter().any(|p| Path::new(p).exists()) {
        missing.push("the Vulkan loader (libvulkan.so.1)");
    }
    let env_icds = ["VK_ICD_FILENAMES", "VK_DRIVER_FILES"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()));
    let has_icd = ICD_DIRS.iter().any(|dir| {
        std::fs::read_dir(dir).is_ok_and(|entries| {
            entries
                .flatten()
                .any(|e| e.path().extension().is_some_and(|x| x == "json"))
        })
    });
    if !env_icds && !has_icd {
        missing.push("a Vulkan driver (ICD)");
    }
    missing
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status").is_ok_and(|s| {
        s.lines()
            .find_map(|l| l.strip_prefix("Uid:"))
            .and_then(|l| l.split_whitespace().nth(1)) // effective uid
            == Some("0")
    })
}

fn ensure_vulkan_driver() -> Result<(), String> {
    let missing = missing_vulkan_parts();
    if missing.is_empty() {
        return Ok(());
    }
    let what = missing.join(" and ");
    let have_apt = Path::new("/usr/bin/apt-get").exists();
    if !(is_root() && have_apt) {
        return Err(format!(
            "missing {what}. Install the Debian package `{DRIVER_PACKAGE}`: \
             sudo apt-get install {DRIVER_PACKAGE}"
        ));
    }
    eprintln!("xtask: missing {what}; installing `{DRIVER_PACKAGE}` with apt-get");
    let run = |args: &[&str]| -> Result<(), String> {
        let status = Command::new("apt-get")
            .args(args)
            .env("DEBIAN_FRONTEND", "noninteractive")
            .status()
            .map_err(|e| format!("apt-get: {e}"))?;
        if status.success() {
            Ok(())
        } else {
            Err(format!("`apt-get {}` failed ({status})", args.join(" ")))
        }
    };
    run(&["update", "-qq"])?;
    run(&["install", "-y", "-qq", DRIVER_PACKAGE])?;
    let still = missing_vulkan_parts();
    if still.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "still missing {} after installing `{DRIVER_PACKAGE}`",
            still.join(" and ")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::Totals;

    /// Under `cargo test` as under `cargo run`, the root is this workspace's.
    #[test]
    fn the_workspace_root_is_this_clones() {
        let root = super::workspace_root().expect("the root exists");
        let manifest = std::fs::read_to_string(root.join("Cargo.toml")).expect("Cargo.toml");
        assert!(manifest.contains("[workspace]"), "{}", root.display());
        assert!(root.join("crates/xtask").is_dir());
    }

    #[test]
    fn totals_sum_cargo_result_lines() {
        let mut t = Totals::default();
        for line in [
            "test result: ok. 8 passed; 0 failed; 1 ignored; 0 measured; 0 filtered out; finished in 0.08s",
            "running 3 tests",
            "test result: FAILED. 1 passed; 2 failed; 0 ignored; 0 measured; 0 filtered out",
            "test totals_sum ... ok",
            "   test result: ok. 0 passed; 0 failed; 0 ignored; 0 measured; 0 filtered out",
        ] {
            t.add_line(line);
        }
        assert_eq!(
            t,
            Totals {
                passed: 9,
                failed: 2,
                ignored: 1,
                skipped_at_run_time: 0
            }
        );
        // Two of the passed ones had recorded a skip.
        t.skip_at_run_time(2);
        assert_eq!(
            t.summary(),
            "total: 7 passed, 2 failed, 3 skipped (1 #[ignore]d, 2 at run time)"
        );
    }
}
