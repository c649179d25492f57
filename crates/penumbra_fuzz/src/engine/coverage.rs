//! LLVM `SanitizerCoverage`'s runtime side, which a fuzzing engine provides: rustc's
//! `-C passes=sancov-module` with `-sanitizer-coverage-inline-8bit-counters` gives every
//! edge of the instrumented crates a byte counter and hands their range to
//! [`__sanitizer_cov_8bit_counters_init`] before `main`;
//! `-sanitizer-coverage-trace-compares` calls the `__sanitizer_cov_trace_*cmp*` hooks
//! with both operands of every comparison, which [`comparison_values`] keeps for the
//! mutator (libFuzzer's "table of recent compares": a magic number or a length the code
//! checks becomes a value to try). These are stable rustc flags: no nightly, no C++.
//!
//! Without the flags (an ordinary build, the replay tests) nothing calls these hooks and
//! [`Counters::get`] finds no counters.
// The hooks are C ABI entry points LLVM's instrumentation calls by name, and the
// counters are memory LLVM owns: both need `unsafe`, confined to this file.
#![allow(unsafe_code)]

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

/// The counter regions the instrumented modules registered (start, end addresses).
static REGIONS: Mutex<Vec<(usize, usize)>> = Mutex::new(Vec::new());

/// Called by each instrumented module's constructor with its counters' range.
#[unsafe(no_mangle)]
pub extern "C" fn __sanitizer_cov_8bit_counters_init(start: *mut u8, stop: *mut u8) {
    let region = (start as usize, stop as usize);
    if let Ok(mut regions) = REGIONS.lock()
        && region.0 < region.1
        && !regions.contains(&region)
    {
        regions.push(region);
    }
}

/// The program-counter table (`-sanitizer-coverage-pc-table`): not needed here.
#[unsafe(no_mangle)]
pub extern "C" fn __sanitizer_cov_pcs_init(_start: *const usize, _stop: *const usize) {}

/// Comparison operands, recorded only while [`record_comparisons`] is on.
const TABLE: usize = 512;
static RECORD: AtomicBool = AtomicBool::new(false);
static NEXT: AtomicUsize = AtomicUsize::new(0);
static VALUES: [AtomicU64; TABLE] = [const { AtomicU64::new(0) }; TABLE];
/// Each value's width in bytes, packed in the top byte of `VALUES`' entries is not
/// possible for 8-byte values, so widths live apart.
static WIDTHS: [AtomicU64; TABLE] = [const { AtomicU64::new(0) }; TABLE];

#[inline]
fn record(a: u64, b: u64, width: u64) {
    if !RECORD.load(Ordering::Relaxed) || a == b {
        return;
    }
    for v in [a, b] {
        // Zero and one are what the mutator tries anyway.
        if v > 1 {
            let i = NEXT.fetch_add(1, Ordering::Relaxed) % TABLE;
            VALUES[i].store(v, Ordering::Relaxed);
            WIDTHS[i].store(width, Ordering::Relaxed);
        }
    }
}

/// Turns recording of comparison operands on or off (on only while a target runs).
pub fn record_comparisons(on: bool) {
    RECORD.store(on, Ordering::Relaxed);
}

/// A value the code compared against, and its width in bytes (1, 2, 4 or 8), from the
/// recent comparisons; `None` while the table is empty.
pub fn comparison_value(pick: usize) -> Option<(u64, usize)> {
    let filled = NEXT.load(Ordering::Relaxed).min(TABLE);
    if filled == 0 {
        return None;
    }
    let i = pick % filled;
    Some((
        VALUES[i].load(Ordering::Relaxed),
        WIDTHS[i].load(Ordering::Relaxed) as usize,
    ))
}

/// How many values [`comparison_value`] can pick from.
pub fn comparison_values() -> usize {
    NEXT.load(Ordering::Relaxed).min(TABLE)
}

macro_rules! cmp_hooks {
    ($($name:ident: $t:ty, $w:expr;)*) => {$(
        /// A comparison hook (`-sanitizer-coverage-trace-compares`).
        #[unsafe(no_mangle)]
        pub extern "C" fn $name(a: $t, b: $t) {
            record(a as u64, b as u64, $w);
        }
    )*};
}

cmp_hooks! {
    __sanitizer_cov_trace_cmp1: u8, 1;
    __sanitizer_cov_trace_cmp2: u16, 2;
    __sanitizer_cov_trace_cmp4: u32, 4;
    __sanitizer_cov_trace_cmp8: u64, 8;
    __sanitizer_cov_trace_const_cmp1: u8, 1;
    __sanitizer_cov_trace_const_cmp2: u16, 2;
    __sanitizer_cov_trace_const_cmp4: u32, 4;
    __sanitizer_cov_trace_const_cmp8: u64, 8;
}

/// A `switch`'s value and cases: `cases[0]` is their count, `cases[1]` the value's
/// width in bits, the cases follow.
///
/// # Safety
/// Called by LLVM's instrumentation with a table it emitted.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn __sanitizer_cov_trace_switch(value: u64, cases: *const u64) {
    if !RECORD.load(Ordering::Relaxed) || cases.is_null() {
        return;
    }
    // SAFETY: LLVM's table holds `2 + cases[0]` words.
    let (count, bits) = unsafe { (*cases, *cases.add(1)) };
    for k in 0..count.min(4) {
        // SAFETY: `k < count`, inside the table.
        let case = unsafe { *cases.add(2 + k as usize) };
        record(value, case, (bits / 8).max(1));
    }
}

/// The instrumented edges' counters.
pub struct Counters {
    regions: Vec<(usize, usize)>,
}

impl Counters {
    /// The regions registered so far (all of them once `main` runs).
    pub fn get() -> Self {
        let regions = REGIONS.lock().map(|r| r.clone()).unwrap_or_default();
        Self { regions }
    }

    /// Instrumented edges in all.
    pub fn len(&self) -> usize {
        self.regions.iter().map(|(a, b)| b - a).sum()
    }

    /// No instrumented code: the binary was built without the coverage flags.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Zeroes every counter (before a run).
    pub fn clear(&self) {
        for &(start, end) in &self.regions {
            // SAFETY: the range is the counters' section LLVM registered, live for the
            // whole program; writing zeroes races only with other counter increments,
            // which the instrumentation itself makes non-atomically.
            unsafe { std::ptr::write_bytes(start as *mut u8, 0, end - start) };
        }
    }

    /// Calls `f(edge, count)` for every counter that is not zero.
    pub fn for_each_hit(&self, mut f: impl FnMut(usize, u8)) {
        let mut base = 0;
        for &(start, end) in &self.regions {
            let len = end - start;
            // SAFETY: as in `clear`; the counters are read as they are (volatile, so
            // the reads are not folded with the writes the target made).
            let counters = start as *const u8;
            let mut i = 0;
            while i + 8 <= len {
                // SAFETY: `i + 8 <= len`, inside the region.
                let word = unsafe { std::ptr::read_volatile(counters.add(i).cast::<[u8; 8]>()) };
                if u64::from_ne_bytes(word) != 0 {
                    for (k, &c) in word.iter().enumerate() {
                        if c != 0 {
                            f(base + i + k, c);
                        }
                    }
                }
                i += 8;
            }
            while i < len {
                // SAFETY: `i < len`, inside the region.
                let c = unsafe { std::ptr::read_volatile(counters.add(i)) };
                if c != 0 {
                    f(base + i, c);
                }
                i += 1;
            }
            base += len;
        }
    }
}
