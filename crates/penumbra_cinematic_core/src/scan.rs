//! Exclusive prefix sums over many items on the GPU, in three passes that every
//! workgroup of a large dispatch shares (the reduce-then-scan of Merrill and Garland,
//! "Single-pass Parallel Prefix Scan with Decoupled Look-back", NVIDIA 2016, §3, without
//! the look-back: two dispatches more, but no forward-progress guarantee needed, which
//! WebGPU does not give).
//!
//! 1. **Reduce** — one workgroup of [`SCAN_THREADS`] per [`GROUP_ITEMS`] items: each
//!    thread sums its [`ITEMS_PER_THREAD`] consecutive items, the workgroup sums the
//!    threads' sums; one sum per group.
//! 2. **Scan the groups' sums** — one workgroup: each thread a run of
//!    `⌈groups / SCAN_THREADS⌉` sums; the runs' sums scanned in the workgroup; each
//!    group's sum becomes its first offset. The total is known here.
//! 3. **Place** — the reduce's workgroups again: each thread's items placed from its
//!    group's offset plus the workgroup's scan of the threads' sums.
//!
//! The offsets are the sequential exclusive scan's, whatever the thread count or timing:
//! every sum is over a fixed run in a fixed order (unsigned integers, so even the
//! grouping does not matter except for saturation, which the users apply per addition).
//! A thread reads at most `2 · ITEMS_PER_THREAD + ⌈groups / SCAN_THREADS⌉` items in
//! turn ([`ScanPlan::serial_reads`]): 10 for a 3840×2160 view's 518,400 bokeh blocks,
//! where one workgroup alone (the earlier design) read 4,050.
//!
//! Users: the bokeh sprites' compaction (`shaders/dof/compact.wgsl`) and the
//! tessellation's allocation (`shaders/tessellation/tessellate.wgsl`). The WGSL
//! constants equal these (a test reads the shaders).

/// Threads of each scan workgroup (the WGSL `SCAN_THREADS`).
pub const SCAN_THREADS: u32 = 256;
/// Consecutive items each thread of the reduce and place passes reads (the WGSL
/// `ITEMS_PER_THREAD`).
pub const ITEMS_PER_THREAD: u32 = 4;
/// Items per workgroup of the reduce and place passes (the WGSL `GROUP_ITEMS`).
pub const GROUP_ITEMS: u32 = SCAN_THREADS * ITEMS_PER_THREAD;

/// The dispatches of one scan over `items` items.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanPlan {
    /// Items scanned.
    pub items: u32,
    /// Workgroups of the reduce and place passes (one per [`GROUP_ITEMS`] items).
    pub groups: u32,
}

impl ScanPlan {
    /// The plan for `items` items.
    pub fn new(items: u32) -> Self {
        Self {
            items,
            groups: items.div_ceil(GROUP_ITEMS),
        }
    }

    /// Elements of the groups' sums buffer (at least one, so it can be bound).
    pub fn group_sums_len(&self) -> u32 {
        self.groups.max(1)
    }

    /// Workgroups of the three passes: reduce, scan of the groups' sums, place.
    pub fn workgroups(&self) -> [u32; 3] {
        [self.groups, 1, self.groups]
    }

    /// The longest run of items one thread reads in turn over the three passes: its
    /// items twice (reduce, place) and its run of the groups' sums.
    pub fn serial_reads(&self) -> u32 {
        2 * ITEMS_PER_THREAD.min(self.items) + self.groups.div_ceil(SCAN_THREADS)
    }

    /// Items of thread `thread` of group `group` in the reduce and place passes.
    pub fn thread_items(&self, group: u32, thread: u32) -> std::ops::Range<u32> {
        let first = (group * GROUP_ITEMS + thread * ITEMS_PER_THREAD).min(self.items);
        first..(first + ITEMS_PER_THREAD).min(self.items)
    }

    /// Groups' sums of thread `thread` in the scan of the groups' sums.
    pub fn thread_groups(&self, thread: u32) -> std::ops::Range<u32> {
        let run = self.groups.div_ceil(SCAN_THREADS);
        let first = (thread * run).min(self.groups);
        first..(first + run).min(self.groups)
    }
}

/// The three passes on the CPU, run as the shaders run them (every thread's run), with
/// saturating additions: each item's first offset and the total.
pub fn exclusive_scan(counts: &[u32]) -> (Vec<u32>, u32) {
    let items = u32::try_from(counts.len()).expect("a u32 count of items");
    let plan = ScanPlan::new(items);
    let run_sum = |r: std::ops::Range<u32>, of: &dyn Fn(u32) -> u32| {
        r.fold(0u32, |s, k| s.saturating_add(of(k)))
    };
    // 1. Reduce.
    let mut group_sums: Vec<u32> = (0..plan.groups)
        .map(|g| {
            (0..SCAN_THREADS).fold(0u32, |s, t| {
                s.saturating_add(run_sum(plan.thread_items(g, t), &|k| counts[k as usize]))
            })
        })
        .collect();
    // 2. The groups' sums become their offsets.
    let mut total = 0u32;
    for t in 0..SCAN_THREADS {
        let run = plan.thread_groups(t);
        let mut offset = total;
        total = total.saturating_add(run_sum(run.clone(), &|g| group_sums[g as usize]));
        for g in run {
            let c = group_sums[g as usize];
            group_sums[g as usize] = offset;
            offset = offset.saturating_add(c);
        }
    }
    // 3. Place.
    let mut offsets = vec![0; counts.len()];
    for g in 0..plan.groups {
        let mut offset = group_sums[g as usize];
        for t in 0..SCAN_THREADS {
            for k in plan.thread_items(g, t) {
                offsets[k as usize] = offset;
                offset = offset.saturating_add(counts[k as usize]);
            }
        }
    }
    (offsets, total)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The offsets are the sequential scan's, for counts around every boundary (a
    /// thread's run, a group, the groups' scan going past one per thread).
    #[test]
    fn offsets_are_the_sequential_scan() {
        let mut seed = 0x9e37_79b9u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for n in [
            0,
            1,
            3,
            4,
            5,
            GROUP_ITEMS - 1,
            GROUP_ITEMS,
            GROUP_ITEMS + 1,
            SCAN_THREADS * GROUP_ITEMS + 7,
            600_000,
        ] {
            let counts: Vec<u32> = (0..n).map(|_| next() % 5).collect();
            let (offsets, total) = exclusive_scan(&counts);
            let mut sum = 0u32;
            for (k, (&c, &o)) in counts.iter().zip(&offsets).enumerate() {
                assert_eq!(o, sum, "{n} items: item {k}");
                sum += c;
            }
            assert_eq!(total, sum, "{n} items");
        }
        // Saturation rather than wrapping.
        let (offsets, total) = exclusive_scan(&[u32::MAX - 1, 5, 1]);
        assert_eq!(
            (offsets, total),
            (vec![0, u32::MAX - 1, u32::MAX], u32::MAX)
        );
    }

    /// The trap the plan removes: a 4K view's bokeh blocks (960 × 540) scanned by one
    /// workgroup made each thread read 2 × 2,025 counts in turn. Every thread now reads
    /// a few, and the work is spread over hundreds of workgroups.
    #[test]
    fn a_4k_view_reads_few_items_per_thread() {
        let blocks = 960 * 540;
        let plan = ScanPlan::new(blocks);
        eprintln!(
            "{blocks} items: {} workgroups, {} serial reads per thread",
            plan.groups,
            plan.serial_reads()
        );
        assert!(plan.serial_reads() <= 16, "{plan:?}");
        assert!(plan.groups >= blocks / GROUP_ITEMS, "{plan:?}");
        // Every item is some thread's, once.
        let mut seen = vec![0u8; blocks as usize];
        for g in 0..plan.groups {
            for t in 0..SCAN_THREADS {
                for k in plan.thread_items(g, t) {
                    seen[k as usize] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
        let covered: u32 = (0..SCAN_THREADS)
            .map(|t| plan.thread_groups(t).len() as u32)
            .sum();
        assert_eq!(covered, plan.groups);
        // 8K still reads few (the groups' scan grows by one read per 262,144 items).
        assert!(ScanPlan::new(1920 * 1080).serial_reads() <= 16);
    }

    /// The shaders use the same constants.
    #[test]
    fn the_shaders_use_these_constants() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders/");
        for file in ["dof/compact.wgsl", "tessellation/tessellate.wgsl"] {
            let source = std::fs::read_to_string(format!("{root}{file}")).expect(file);
            for line in [
                format!("const SCAN_THREADS: u32 = {SCAN_THREADS}u;"),
                format!("const ITEMS_PER_THREAD: u32 = {ITEMS_PER_THREAD}u;"),
            ] {
                assert!(source.contains(&line), "{file}: {line}");
            }
        }
    }
}
