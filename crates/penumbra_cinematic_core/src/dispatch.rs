//! Compute dispatches over more threads than one dimension holds.
//!
//! WebGPU guarantees 65,535 workgroups per dimension
//! (`maxComputeWorkgroupsPerDimension`): a one-dimensional dispatch of 64-thread groups
//! stops at 4,194,240 threads (hair points, tessellation patches). [`workgroups_2d`]
//! folds the groups into rows of at most [`MAX_WORKGROUPS_PER_DIMENSION`]; the shader
//! takes its thread's index as `(group.y · groups.x + group.x) · size + local` and
//! returns past the count (`penumbra::cinematic::dispatch`'s `linear_index`).

/// The guaranteed workgroups per dispatch dimension.
pub const MAX_WORKGROUPS_PER_DIMENSION: u32 = 65_535;

/// The `(x, y, 1)` workgroup counts covering `threads` threads in groups of
/// `group_size`: `x` at most [`MAX_WORKGROUPS_PER_DIMENSION`], `x · y · group_size ≥
/// threads`, with fewer than one row of groups to spare. `(0, 0, 0)` for no thread.
pub fn workgroups_2d(threads: u32, group_size: u32) -> [u32; 3] {
    let groups = threads.div_ceil(group_size.max(1));
    if groups == 0 {
        return [0, 0, 0];
    }
    let x = groups.min(MAX_WORKGROUPS_PER_DIMENSION);
    [x, groups.div_ceil(x), 1]
}

/// The linear index of a thread (the shader's `linear_index`).
pub fn linear_index(group: [u32; 2], groups_x: u32, group_size: u32, local: u32) -> u64 {
    (u64::from(group[1]) * u64::from(groups_x) + u64::from(group[0])) * u64::from(group_size)
        + u64::from(local)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every thread count, up to past 2³², is covered within the per-dimension limit,
    /// each index once; a one-dimensional dispatch (the old hair and factor passes)
    /// breaks the limit from 4,194,241 threads.
    #[test]
    fn large_counts_fit_the_limit_and_cover_every_thread() {
        for threads in [
            1,
            63,
            64,
            65,
            4_194_240,
            4_194_241,
            5_000_000,
            100_000_000,
            u32::MAX,
        ] {
            let [x, y, z] = workgroups_2d(threads, 64);
            assert!(x <= MAX_WORKGROUPS_PER_DIMENSION && y <= MAX_WORKGROUPS_PER_DIMENSION);
            assert_eq!(z, 1);
            let covered = u64::from(x) * u64::from(y) * 64;
            assert!(covered >= u64::from(threads), "{threads}: {covered}");
            assert!(
                covered - u64::from(threads) < u64::from(x) * 64,
                "{threads}: one row spare"
            );
            // The last thread's index is the count less one, reachable.
            let last = linear_index([x - 1, y - 1], x, 64, 63);
            assert_eq!(last + 1, covered);
        }
        assert_eq!(workgroups_2d(0, 64), [0, 0, 0]);
        let one_dimension = 5_000_000u32.div_ceil(64);
        assert!(
            one_dimension > MAX_WORKGROUPS_PER_DIMENSION,
            "{one_dimension}"
        );
        // Small counts stay one row (the common case changes nothing).
        assert_eq!(workgroups_2d(9_000 * 5, 64), [704, 1, 1]);
    }
}
