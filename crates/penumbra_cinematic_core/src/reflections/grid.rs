//! The caster grid of reflection shadows: where a tile's caster list overflows (more
//! than `MAX_TILE_CASTERS` objects within reach of its rays — the glossy surfaces of a
//! crowd, whose mirror rays leave every way), each segment of a pixel's march gathers
//! its objects from a uniform grid of the casters' bounding-sphere centres instead of
//! testing every object (`reflections/spheres.wgsl` builds it once per frame and view,
//! `reflections/trace.wgsl`'s `gather_from_grid` reads it).
//!
//! **The grid** spans the box of the bounded casters' centres: cubic cells of side
//! `max extent / GRID_DIM`, at most [`GRID_DIM`] along each axis. Each caster lies in the
//! one cell holding its centre (a *loose* grid: no object is listed twice) unless its
//! radius exceeds a cell or it is unbounded: then it is *large*, and every gather tests
//! it. Building it is a counting sort: bounds, counts, one scan, fill.
//!
//! Tiles whose list holds more than [`GRID_OVER_LIST`] casters gather from the grid too.
//!
//! **A gather** of the segment `a`–`b` with the cone's reach `cone · t1` visits the cells
//! of the segment's box widened by that reach and the largest listed radius (a caster
//! whose sphere comes within the reach of the segment has its centre in that box), plus
//! the large casters, and applies the same sphere test as a gather from every object
//! ([`super::pass::shadow_casters`]): the same set, so the same march — culling only,
//! changing no pixel. A box of more cells than there are objects falls back to testing
//! every object. The list's order is not the brute force's (the GPU fills cells with
//! atomics), which the march does not see: it takes the minimum of the distances.

use glam::{UVec3, Vec3};
use std::cell::Cell;

/// A tile whose caster list is longer than this gathers from the grid too (the same
/// casters: its list holds every object its pixels' segments can keep), where the grid's
/// ~35 sphere tests per gather on a crowd beat the list's (`trace.wgsl`'s
/// `gather_casters`; the model's gathers give the same set either way).
pub const GRID_OVER_LIST: usize = 64;

/// Most cells along one axis of the grid.
pub const GRID_DIM: u32 = 32;
/// Cells the GPU grid reserves (`GRID_DIM³`).
pub const GRID_CELLS: u32 = GRID_DIM * GRID_DIM * GRID_DIM;
/// Words of the GPU grid's header (`reflections/spheres.wgsl`): bounds keys, the largest
/// listed radius, the large count, the resolved frame.
pub const GRID_HEADER_WORDS: u32 = 16;

/// Words the GPU grid takes in the view's list buffer for `slots` object slots: the
/// header, the cells' counts and offsets, the listed objects and the large ones.
pub fn grid_words(slots: u32) -> u64 {
    u64::from(GRID_HEADER_WORDS) + 2 * u64::from(GRID_CELLS) + 1 + 2 * u64::from(slots)
}

/// The grid's frame from its centres' box `lo`–`hi`: the cell side (metres) and the
/// cells per axis (the shader's `grid_frame`, same arithmetic).
pub fn grid_frame(lo: Vec3, hi: Vec3) -> (f32, UVec3) {
    let extent = (hi - lo).max(Vec3::ZERO);
    let cell = (extent.max_element() / GRID_DIM as f32).max(1e-4);
    let cells = |e: f32| (e / cell).min((GRID_DIM - 1) as f32) as u32 + 1;
    let dims = UVec3::new(cells(extent.x), cells(extent.y), cells(extent.z));
    (cell, dims)
}

/// A uniform grid of the casters' bounding spheres (module docs).
#[derive(Debug)]
pub struct CasterGrid {
    /// The lowest corner (the centres' box), metres.
    pub lo: Vec3,
    /// Cell side, metres.
    pub cell: f32,
    /// Cells per axis (zero: no listed caster).
    pub dims: UVec3,
    /// The largest radius among the listed casters, metres.
    pub max_radius: f32,
    /// Per cell (x fastest, then y, then z), its casters, ascending.
    pub cells: Vec<Vec<usize>>,
    /// Unbounded casters and those wider than a cell, ascending.
    pub large: Vec<usize>,
    /// Sphere tests made by gathers so far (a measure of the work).
    pub tested: Cell<u64>,
    /// Gathers so far (each from every object would test every sphere).
    pub gathers: Cell<u64>,
}

/// What a gather from the grid found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GridGather {
    /// The kept objects, ascending (at most `MAX_SHADOW_CASTERS`).
    Kept(Vec<usize>),
    /// More than `MAX_SHADOW_CASTERS`: march every object there.
    Overflow,
    /// The segment's box covers more cells than there are objects: gather from every
    /// object instead.
    TooWide,
}

impl CasterGrid {
    /// The grid of `spheres` (centre and radius per object; `None`: unbounded).
    pub fn new(spheres: &[Option<(Vec3, f32)>]) -> Self {
        let centres = spheres.iter().flatten().map(|(c, _)| *c);
        let lo = centres.clone().fold(Vec3::splat(f32::INFINITY), Vec3::min);
        let hi = centres.fold(Vec3::splat(f32::NEG_INFINITY), Vec3::max);
        let (cell, dims) = if lo.x.is_finite() {
            grid_frame(lo, hi)
        } else {
            (1.0, UVec3::ZERO)
        };
        let mut grid = CasterGrid {
            lo,
            cell,
            dims,
            max_radius: 0.0,
            cells: vec![Vec::new(); (dims.x * dims.y * dims.z) as usize],
            large: Vec::new(),
            tested: Cell::new(0),
            gathers: Cell::new(0),
        };
        for (i, sphere) in spheres.iter().enumerate() {
            match sphere {
                Some((c, r)) if *r <= cell => {
                    let at = grid.cell_index(grid.cell_of(*c));
                    grid.cells[at].push(i);
                    grid.max_radius = grid.max_radius.max(*r);
                }
                _ => grid.large.push(i),
            }
        }
        grid
    }

    /// The cell holding point `p` (clamped into the grid).
    pub fn cell_of(&self, p: Vec3) -> UVec3 {
        let f = ((p - self.lo) / self.cell).max(Vec3::ZERO);
        UVec3::new(f.x as u32, f.y as u32, f.z as u32).min(self.dims.saturating_sub(UVec3::ONE))
    }

    fn cell_index(&self, c: UVec3) -> usize {
        ((c.z * self.dims.y + c.y) * self.dims.x + c.x) as usize
    }

    /// The cells a gather of the segment `a`–`b` visits, widened by `reach`: `None`
    /// when no cell can hold a kept caster.
    pub fn cell_range(&self, a: Vec3, b: Vec3, reach: f32) -> Option<(UVec3, UVec3)> {
        if self.dims.x == 0 {
            return None;
        }
        let widen = (self.max_radius + reach) * 1.001 + 1e-3;
        let lo = (a.min(b) - widen - self.lo) / self.cell;
        let hi = (a.max(b) + widen - self.lo) / self.cell;
        let dims = self.dims.as_vec3();
        if hi.cmplt(Vec3::ZERO).any() || lo.cmpge(dims).any() {
            return None;
        }
        let lo = lo.max(Vec3::ZERO);
        let hi = hi.min(dims - 1.0);
        Some((
            UVec3::new(lo.x as u32, lo.y as u32, lo.z as u32),
            UVec3::new(hi.x as u32, hi.y as u32, hi.z as u32),
        ))
    }

    /// The objects of `spheres` (those the grid was built from) whose bounding sphere
    /// comes within `cone · t1` of the ray `origin + dir t` between `t0` and `t1`, as
    /// [`super::pass::shadow_casters`] keeps them from every object (module docs).
    pub fn gather(
        &self,
        spheres: &[Option<(Vec3, f32)>],
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        t1: f32,
        cone: f32,
    ) -> GridGather {
        self.gathers.set(self.gathers.get() + 1);
        let (a, b) = (origin + dir * t0, origin + dir * t1);
        let reach = cone * t1;
        if !(a.is_finite() && b.is_finite() && reach.is_finite()) {
            return GridGather::TooWide;
        }
        let range = self.cell_range(a, b, reach);
        let cells = range.map_or(0, |(lo, hi)| {
            let n = hi - lo + UVec3::ONE;
            u64::from(n.x) * u64::from(n.y) * u64::from(n.z)
        });
        if cells > spheres.len() as u64 {
            return GridGather::TooWide;
        }
        let mut kept = Vec::new();
        let mut test = |i: usize| -> bool {
            self.tested.set(self.tested.get() + 1);
            let keep = super::pass::keeps_caster(spheres[i], a, b, reach);
            if keep {
                if kept.len() == super::pass::MAX_SHADOW_CASTERS {
                    return false;
                }
                kept.push(i);
            }
            true
        };
        for &i in &self.large {
            if !test(i) {
                return GridGather::Overflow;
            }
        }
        if let Some((lo, hi)) = range {
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        for &i in &self.cells[self.cell_index(UVec3::new(x, y, z))] {
                            if !test(i) {
                                return GridGather::Overflow;
                            }
                        }
                    }
                }
            }
        }
        kept.sort_unstable();
        GridGather::Kept(kept)
    }
}

#[cfg(test)]
mod tests {
    use super::super::pass::shadow_casters;
    use super::*;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 40) as f32) / (1u64 << 24) as f32
        }
        fn vec(&mut self, scale: Vec3) -> Vec3 {
            Vec3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * 2.0 * scale
        }
    }

    /// A crowd: `n` casters in a flat box, some large, some unbounded, a few sharing a
    /// centre on a cell's corner.
    fn crowd(rng: &mut Rng, n: usize) -> Vec<Option<(Vec3, f32)>> {
        (0..n)
            .map(|i| match i % 97 {
                0 => None,
                1 => Some((rng.vec(Vec3::new(40.0, 1.0, 25.0)), 12.0)),
                2 | 3 => Some((Vec3::new(0.0, 0.0, 0.0), 0.5)),
                _ => Some((rng.vec(Vec3::new(40.0, 1.0, 25.0)), 0.2 + 1.2 * rng.next())),
            })
            .collect()
    }

    /// A grid's gather keeps exactly what a gather from every object keeps (or says to
    /// fall back to it), over random segments of every length and cone through a crowd.
    #[test]
    fn the_grid_gathers_what_every_object_gathers() {
        let mut rng = Rng(7);
        let (mut compared, mut wide) = (0, 0);
        for n in [1, 40, 400, 1500] {
            let spheres = crowd(&mut rng, n);
            let grid = CasterGrid::new(&spheres);
            for _ in 0..3000 {
                let origin = rng.vec(Vec3::new(45.0, 4.0, 30.0));
                let dir = rng.vec(Vec3::ONE).normalize_or(Vec3::X);
                let t1 = 60.0 * rng.next() * rng.next();
                let t0 = t1 * rng.next();
                let cone = 0.3 * rng.next() * rng.next();
                let every = shadow_casters(&spheres, None, origin, dir, t0, t1, cone);
                match grid.gather(&spheres, origin, dir, t0, t1, cone) {
                    GridGather::Kept(kept) => assert_eq!(Some(kept), every, "{n} objects"),
                    GridGather::Overflow => assert_eq!(every, None, "{n} objects"),
                    GridGather::TooWide => wide += 1,
                }
                compared += 1;
            }
        }
        println!("{compared} gathers, {wide} too wide for the grid");
        assert!(wide < compared / 4, "{wide} of {compared} fell back");
    }

    /// Short segments in a crowd of 1,000 test a few dozen spheres, not 1,000.
    #[test]
    fn a_crowd_is_gathered_from_a_few_cells() {
        let mut rng = Rng(11);
        let spheres: Vec<_> = (0..1000)
            .map(|_| Some((rng.vec(Vec3::new(40.0, 0.5, 24.0)), 0.4 + 0.6 * rng.next())))
            .collect();
        let grid = CasterGrid::new(&spheres);
        assert!(grid.large.is_empty());
        let gathers = 1000;
        for _ in 0..gathers {
            let origin = rng.vec(Vec3::new(38.0, 0.5, 22.0));
            let dir = rng.vec(Vec3::ONE).normalize_or(Vec3::X);
            let kept = grid.gather(&spheres, origin, dir, 0.0, 5.0, 0.05);
            assert!(!matches!(kept, GridGather::TooWide));
        }
        let per_gather = grid.tested.get() as f64 / f64::from(gathers);
        println!("{per_gather:.1} sphere tests per gather, against 1000");
        assert!(per_gather < 100.0, "{per_gather} sphere tests per gather");
    }

    /// Degenerate input: no object, only unbounded ones, every centre at one point, a
    /// NaN ray: no panic, and the gathers still agree with every object's.
    #[test]
    fn degenerate_grids_still_gather_right() {
        let point = vec![Some((Vec3::ONE, 0.5)); 40];
        for spheres in [vec![], vec![None; 3], point] {
            let grid = CasterGrid::new(&spheres);
            let every = shadow_casters(
                &spheres,
                None,
                Vec3::ZERO,
                Vec3::ONE.normalize(),
                0.0,
                4.0,
                0.1,
            );
            match grid.gather(&spheres, Vec3::ZERO, Vec3::ONE.normalize(), 0.0, 4.0, 0.1) {
                GridGather::Kept(kept) => assert_eq!(Some(kept), every),
                GridGather::Overflow => assert_eq!(every, None),
                GridGather::TooWide => {}
            }
            let nan = grid.gather(&spheres, Vec3::NAN, Vec3::X, 0.0, 1.0, 0.1);
            assert_eq!(nan, GridGather::TooWide);
        }
    }
}
