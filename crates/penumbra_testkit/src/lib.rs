//! Test support shared by every Penumbra crate's tests, with no dependency (it builds
//! in a second, so the Bevy-free crates keep their fast tests):
//!
//! - [`is_ci`]: the one rule for reading `CI`.
//! - [`skip`]: a test that cannot run here (no GPU adapter, no `../shared`) says so; under
//!   CI that is a failure, never a skip. `cargo xtask test` counts skips as skipped, not
//!   passed: it sets [`SKIP_LOG_ENV`] to a file each skip appends a line to.
//! - [`shared_dir`]: `../shared/<sub>` beside the checkout, or a reported skip.
//! - [`XorShift`]: a tiny deterministic generator for test scenes.
//! - [`Awkward`]: values a property test throws at settings (NaN, infinities, zero,
//!   negative, tiny, huge, the integer limits, and ordinary ones), and [`assert_finite`]
//!   for what resolving them gives.

use std::io::Write;
use std::path::PathBuf;

/// The environment variable naming the file skipped tests append to (one line each:
/// `test<TAB>reason`); `cargo xtask test` sets it and reads the file afterwards.
pub const SKIP_LOG_ENV: &str = "PENUMBRA_SKIP_LOG";

/// Whether this run is CI: `CI` is set to anything but empty, `0` or `false` (any case).
/// The one rule every test and tool uses.
pub fn is_ci() -> bool {
    ci_value(std::env::var("CI").ok().as_deref())
}

/// [`is_ci`] for a given value of `CI`.
pub fn ci_value(value: Option<&str>) -> bool {
    value.is_some_and(|v| {
        let v = v.trim();
        !(v.is_empty() || v == "0" || v.eq_ignore_ascii_case("false"))
    })
}

/// Reports that `test` cannot run here because of `reason`, and returns (the test should
/// return early). Under CI, panics instead: CI must run every test.
pub fn skip(test: &str, reason: &str) {
    assert!(
        !is_ci(),
        "{test}: {reason}; CI is set, so this is a failure"
    );
    // Written to the process's stderr directly, so the message shows even when the
    // test harness captures output.
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: {reason}");
    if let Some(path) = std::env::var_os(SKIP_LOG_ENV) {
        let line = format!("{test}\t{}\n", reason.replace(['\n', '\t'], " "));
        let appended = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .and_then(|mut f| f.write_all(line.as_bytes()));
        if let Err(e) = appended {
            let _ = writeln!(std::io::stderr(), "could not record the skip: {e}");
        }
    }
}

/// `../shared/<sub>` beside the repository checkout (the workspace root is found from
/// `manifest_dir`, a crate's `CARGO_MANIFEST_DIR`), or `None` after reporting `test` as
/// skipped (a failure under CI).
pub fn shared_dir(test: &str, manifest_dir: &str, sub: &str) -> Option<PathBuf> {
    // `cargo test` sets the crate's directory at run time too: prefer it, so a test
    // binary built in another checkout of the same target dir (cargo reuses it) looks
    // beside this one.
    let runtime = std::env::var("CARGO_MANIFEST_DIR").ok();
    let manifest_dir = runtime.as_deref().unwrap_or(manifest_dir);
    let mut root = PathBuf::from(manifest_dir);
    while !root.join("Cargo.lock").exists() {
        if !root.pop() {
            break;
        }
    }
    let dir = root.join("..").join("shared").join(sub);
    if dir.is_dir() {
        return Some(dir);
    }
    skip(
        test,
        &format!(
            "{} not found (real meshes and scenes live in ../shared)",
            dir.display()
        ),
    );
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_rule_for_ci_values() {
        for (value, want) in [
            (None, false),
            (Some(""), false),
            (Some("0"), false),
            (Some("false"), false),
            (Some("FALSE"), false),
            (Some(" false "), false),
            (Some("true"), true),
            (Some("1"), true),
            (Some("yes"), true),
            (Some("github-actions"), true),
        ] {
            assert_eq!(ci_value(value), want, "{value:?}");
        }
    }
}

/// A tiny deterministic random generator (xorshift32) for test and bench scenes: the
/// same numbers on every machine and thread count.
#[derive(Clone, Debug)]
pub struct XorShift(pub u32);

impl XorShift {
    /// The next number in `[0, 1)` (24 bits).
    pub fn unit(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        (self.0 >> 8) as f32 / (1 << 24) as f32
    }

    /// The next number in `[a, b)`.
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.unit()
    }
}

/// Fails, naming `what` and the `input` it came from, when `value`'s debug form shows a
/// NaN or an infinity (what property tests ask of every resolved setting).
pub fn assert_finite(what: &str, value: &impl std::fmt::Debug, input: &impl std::fmt::Debug) {
    let text = format!("{value:?}");
    assert!(
        !has_non_finite(&text),
        "{what}: resolved to a non-finite value: {text}\n  from {input:?}"
    );
}

/// Whether a value's debug form shows a NaN or an infinity.
pub fn has_non_finite(debug: &str) -> bool {
    debug.contains("NaN") || debug.contains("inf")
}

/// Values for property tests of settings and inputs: each call returns, with equal
/// odds, one of the classic troublemakers (NaN, ±∞, ±0, the smallest normal and
/// subnormal, ±`f32::MAX`, 1e-7, 1e7, −1) or an ordinary value, so a few thousand draws
/// try every field at every kind of value (`proptest` is not in the offline registry this
/// project builds from; this is its generator without the shrinking).
pub struct Awkward(XorShift);

impl Awkward {
    /// A generator from `seed` (any value but 0).
    pub fn new(seed: u32) -> Self {
        Self(XorShift(seed.max(1)))
    }

    /// A number in `0..n`.
    pub fn below(&mut self, n: u32) -> u32 {
        ((self.0.unit() * n as f32) as u32).min(n.saturating_sub(1))
    }

    /// A float: a troublemaker half the time, else ordinary in `[-4, 12)`.
    pub fn f32(&mut self) -> f32 {
        const SPECIAL: [f32; 14] = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            1e-45,
            f32::MAX,
            f32::MIN,
            1e-7,
            1e7,
            -1.0,
            1.0,
            0.5,
        ];
        if self.below(2) == 0 {
            SPECIAL[self.below(SPECIAL.len() as u32) as usize]
        } else {
            self.0.range(-4.0, 12.0)
        }
    }

    /// An integer: 0, 1, 2, a power of two, `u32::MAX` or an ordinary one below 100.
    pub fn u32(&mut self) -> u32 {
        match self.below(6) {
            0 => 0,
            1 => 1,
            2 => 2,
            3 => 1 << self.below(32),
            4 => u32::MAX,
            _ => self.below(100),
        }
    }

    /// A coin toss.
    pub fn bool(&mut self) -> bool {
        self.below(2) == 0
    }
}

/// The radical inverse of `i` in `base`: the `i`-th point of the van der Corput sequence,
/// in `[0, 1)`. Three bases (2, 3, 5) give a 3-D Halton set: deterministic points that
/// cover a box evenly, for tests that sample a field.
pub fn radical_inverse(mut i: u32, base: u32) -> f64 {
    let (mut r, mut f) = (0.0, 1.0 / base as f64);
    while i > 0 {
        r += f * (i % base) as f64;
        i /= base;
        f /= base as f64;
    }
    r
}

/// The `i`-th point (from 1) of the 3-D Halton set (bases 2, 3, 5), in `[0, 1)³`.
pub fn halton3(i: u32) -> [f64; 3] {
    [
        radical_inverse(i, 2),
        radical_inverse(i, 3),
        radical_inverse(i, 5),
    ]
}
