//! `cargo xtask fuzz [--seconds N] [--target T]... [--jobs J] [--seed S]`: builds
//! `crates/penumbra_fuzz`'s `penumbra-fuzz` with `SanitizerCoverage` on the crates under
//! test (`crates/penumbra_fuzz/sancov-rustc.sh` as `RUSTC_WRAPPER`, in its own target
//! folder so the ordinary build is untouched), runs every target for N seconds (J at a
//! time), and prints a table: executions, speed, edges reached, corpus size, failures.
//! New corpus entries land in `crates/penumbra_fuzz/corpus/`; failing inputs in
//! `crates/penumbra_fuzz/artifacts/` (copy a fixed one to `regressions/` to replay it).

use std::process::{Command, Stdio};

const TARGETS: [&str; 6] = ["psdf", "obj", "gltf", "hair", "ribbons", "tessellation"];

/// One target's outcome: its JSON report line, or why it failed.
struct Outcome {
    target: String,
    report: Option<String>,
    failure: Option<String>,
}

pub fn fuzz(cargo: &std::ffi::OsStr, args: &[String]) -> Result<(), String> {
    let mut seconds = 60.0f64;
    let mut jobs = 1usize;
    let mut seed = 1u64;
    let mut targets: Vec<String> = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value")).cloned();
        match a.as_str() {
            "--seconds" => {
                seconds = value("--seconds")?
                    .parse()
                    .map_err(|e| format!("--seconds: {e}"))?;
            }
            "--jobs" => {
                jobs = value("--jobs")?
                    .parse()
                    .map_err(|e| format!("--jobs: {e}"))?;
            }
            "--seed" => {
                seed = value("--seed")?
                    .parse()
                    .map_err(|e| format!("--seed: {e}"))?;
            }
            "--target" => {
                let t = value("--target")?;
                if !TARGETS.contains(&t.as_str()) {
                    return Err(format!(
                        "unknown target `{t}` (targets: {})",
                        TARGETS.join(", ")
                    ));
                }
                targets.push(t);
            }
            _ => return Err(format!("unknown argument `{a}`")),
        }
    }
    if targets.is_empty() {
        targets = TARGETS.iter().map(|t| t.to_string()).collect();
    }
    let root = crate::workspace_root()?;
    let target_dir = crate::bench_pack::target_dir(cargo, &root)?.join("fuzz");
    let wrapper = root.join("crates/penumbra_fuzz/sancov-rustc.sh");
    crate::bench_pack::run(
        Command::new(cargo)
            .current_dir(&root)
            .env("RUSTC_WRAPPER", &wrapper)
            .env("CARGO_TARGET_DIR", &target_dir)
            .args([
                "build",
                "--release",
                "-p",
                "penumbra_fuzz",
                "--bin",
                "penumbra-fuzz",
            ]),
    )?;
    let binary = target_dir.join("release/penumbra-fuzz");
    let mut outcomes = Vec::new();
    for batch in targets.chunks(jobs.max(1)) {
        let children: Vec<_> = batch
            .iter()
            .map(|t| {
                eprintln!("xtask: fuzzing {t} for {seconds} s");
                let child = Command::new(&binary)
                    .args([
                        t.as_str(),
                        "--seconds",
                        &seconds.to_string(),
                        "--seed",
                        &seed.to_string(),
                    ])
                    .stdout(Stdio::piped())
                    .spawn();
                (t.clone(), child)
            })
            .collect();
        for (target, child) in children {
            let outcome = match child.and_then(|c| c.wait_with_output()) {
                Err(e) => Outcome {
                    target,
                    report: None,
                    failure: Some(e.to_string()),
                },
                Ok(out) => {
                    let report = String::from_utf8_lossy(&out.stdout)
                        .lines()
                        .last()
                        .map(String::from);
                    let failure = match out.status.code() {
                        Some(0) => None,
                        Some(2) => {
                            Some("panics found (inputs in crates/penumbra_fuzz/artifacts)".into())
                        }
                        Some(3) => Some("a hang (input in crates/penumbra_fuzz/artifacts)".into()),
                        Some(4) => Some(
                            "over the memory limit (input in crates/penumbra_fuzz/artifacts)"
                                .into(),
                        ),
                        _ => Some(format!("exited with {}", out.status)),
                    };
                    Outcome {
                        target,
                        report,
                        failure,
                    }
                }
            };
            outcomes.push(outcome);
        }
    }
    print_table(&outcomes);
    let failed: Vec<&str> = outcomes
        .iter()
        .filter(|o| o.failure.is_some())
        .map(|o| o.target.as_str())
        .collect();
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("failures in {}", failed.join(", ")))
    }
}

/// A number field of a flat JSON line.
fn field(line: &str, name: &str) -> Option<f64> {
    let key = format!("\"{name}\":");
    let start = line.find(&key)? + key.len();
    let end = line[start..].find([',', '}'])? + start;
    line[start..end].parse().ok()
}

fn print_table(outcomes: &[Outcome]) {
    println!(
        "| target | executions | per second | edges reached | instrumented edges | features | corpus | result |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut total = 0.0;
    for o in outcomes {
        let line = o.report.as_deref().unwrap_or("");
        let f = |name| field(line, name).map_or("–".to_string(), |v| format!("{v:.0}"));
        total += field(line, "runs").unwrap_or(0.0);
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            o.target,
            f("runs"),
            f("runs_per_second"),
            f("edges"),
            f("instrumented_edges"),
            f("features"),
            f("corpus"),
            o.failure
                .as_deref()
                .unwrap_or("0 crashes, hangs or out-of-memory"),
        );
    }
    println!("\n{total:.0} executions in all");
}
