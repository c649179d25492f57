//! # `penumbra_df_core`
//!
//! The Bevy-free core of Penumbra's distance-field scene, the data side of Unreal's
//! "all SDFs in one atlas, all objects in one buffer, the CPU sends deltas" design
//! (Wright, *Dynamic Occlusion with Signed Distance Fields*, SIGGRAPH 2015):
//!
//! - [`atlas`]: places SDF volumes in one 3D texture (`R16Float`) under a memory budget,
//!   reusing freed space; reports when it is full so the caller can fall back.
//! - [`object`]: the 128-byte GPU record of one caster instance — world-from-local and
//!   local-from-world 3×4 matrices, conservative scale, atlas location or analytic shape,
//!   flags — and its exact byte encoding (the WGSL struct in
//!   `shaders/df/object.wgsl` is checked against it).
//! - [`table`]: the CPU mirror of the GPU object buffer. It hands out slots (reusing
//!   freed ones), and turns a frame's adds, removes and changes into a compact list of
//!   `(slot, record)` writes: a static scene sends nothing, `k` changes send `O(k)` bytes.
//! - [`heightfield`]: terrain grids as casters, with a conservative distance.
//! - [`query`]: gameplay queries on the CPU — distance, gradient, sphere casts —
//!   against casters' volumes and analytic shapes.
//! - [`shadow`]: the GPU parameters of distance-field shadows (light and mask-pass view
//!   uniforms).
//! - [`clipmap`]: the global distance field's camera-centred clipmaps — layout,
//!   toroidal addressing, scrolling in bricks, dirty regions, the per-frame brick budget
//!   and which bricks are valid.
//! - [`skin_capsules`]: capsules fitted to a skinned mesh's joints, the casters of an
//!   animated character.
//! - [`rebake`]: the GPU re-bake of a posed mesh (a hero character) into its atlas
//!   volume: the cube it fills, the pass's uniform and output layout.
//! - [`cull`]: frustum planes and the oriented-box test the GPU culling pass runs, as the
//!   CPU reference the GPU output is compared with.
//!
//! ## Conventions
//!
//! Glam/Bevy: right-handed, y up, metres, column vectors (`world = M · local`).
//! An object's *local* space is its mesh's space (the units its SDF distances are in).
//! World positions are stored relative to a **tile** — the nearest multiple of
//! [`object::TILE_SIZE`] metres — so that a record stays precise 10⁵ m from the origin:
//! shaders subtract the camera's tile first and work with small camera-relative numbers.

pub mod ao;
pub mod atlas;
pub mod bricks;
pub mod clipmap;
pub mod cull;
pub mod heightfield;
pub mod msaa;
pub mod object;
pub mod particles;
pub mod query;
pub mod rebake;
pub mod shadow;
pub mod skin_capsules;
pub mod table;
