//! Coverage-guided fuzzing of the inputs Penumbra takes from users — `.psdf` fields, OBJ
//! and glTF meshes for the baker, `.hair` files, ribbon meshes and meshes handed to
//! tessellation — on stable Rust, with no C++ fuzzer and no nightly toolchain.
//!
//! `cargo xtask fuzz [--seconds N] [--target T]` builds the `penumbra-fuzz` binary with
//! LLVM's `SanitizerCoverage` on the crates under test (`sancov-rustc.sh`: edge counters
//! and comparison operands, stable `-C passes=sancov-module` flags) and runs
//! [`engine::fuzz`] on each [`Target`] in turn. A memory limit (an allocator that counts
//! live bytes) makes blow-ups findings, as libFuzzer's `-malloc_limit_mb`; a watchdog
//! makes hangs findings.
//!
//! The corpus (`corpus/<target>/`) and every input that ever failed
//! (`regressions/<target>/`) are committed and replayed by `tests/replay.rs` as ordinary
//! tests: CI needs no fuzzer and no instrumentation.

pub mod engine;
mod targets;

pub use targets::Target;

/// The crate's folder (corpus and regressions live under it).
pub fn crate_dir() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
