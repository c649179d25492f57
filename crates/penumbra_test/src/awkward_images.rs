//! Images for property tests of everything that reads a user's image (heightfields,
//! displacement maps, apertures, billboards): every texture format class (8- and 16-bit
//! integers, normalized and not, 16- and 32-bit floats, packed, block-compressed, depth)
//! at every size class (empty, one texel, odd, ordinary, beyond the readers' limits), with
//! CPU data missing, exact (random bytes: NaN and infinite floats included), short and
//! long. A reader must return `Ok` with one finite value per texel, or an error.

use bevy::asset::RenderAssetUsages;
use bevy::image::Image;
use bevy::math::UVec2;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use penumbra_testkit::XorShift;

/// The formats tried.
pub const FORMATS: [TextureFormat; 24] = [
    TextureFormat::R8Unorm,
    TextureFormat::R8Snorm,
    TextureFormat::R8Uint,
    TextureFormat::Rg8Unorm,
    TextureFormat::Rgba8Unorm,
    TextureFormat::Rgba8UnormSrgb,
    TextureFormat::Bgra8Unorm,
    TextureFormat::Bgra8UnormSrgb,
    TextureFormat::Rgba8Snorm,
    TextureFormat::R16Uint,
    TextureFormat::R16Unorm,
    TextureFormat::R16Float,
    TextureFormat::Rg16Uint,
    TextureFormat::Rg16Float,
    TextureFormat::Rgba16Unorm,
    TextureFormat::Rgba16Float,
    TextureFormat::R32Float,
    TextureFormat::R32Uint,
    TextureFormat::Rg32Float,
    TextureFormat::Rgba32Float,
    TextureFormat::Rgb9e5Ufloat,
    TextureFormat::Rgb10a2Unorm,
    TextureFormat::Bc1RgbaUnorm,
    TextureFormat::Depth32Float,
];

/// Sizes tried: none, one texel, odd, ordinary, one past common limits, huge.
pub const SIZES: [(u32, u32); 7] = [
    (0, 0),
    (1, 1),
    (3, 5),
    (64, 32),
    (1025, 1),
    (8193, 1),
    (60_000, 60_000),
];

/// How the CPU data relates to the size.
#[derive(Clone, Copy, Debug)]
pub enum Data {
    /// No CPU copy.
    Missing,
    /// As long as the size and format say.
    Exact,
    /// Half that (rounded down).
    Short,
    /// Seven bytes more.
    Long,
}

/// Every format × size × data case as (a label, the image). Huge sizes get only missing
/// or short (a few bytes) data, so the set stays small in memory.
pub fn awkward_images(seed: u32) -> Vec<(String, Image)> {
    let mut rng = XorShift(seed.max(1));
    let mut out = Vec::new();
    for format in FORMATS {
        for (w, h) in SIZES {
            for data in [Data::Missing, Data::Exact, Data::Short, Data::Long] {
                let block = format.block_dimensions();
                let blocks = (w.div_ceil(block.0) as u64) * (h.div_ceil(block.1) as u64);
                let bytes = blocks * u64::from(format.block_copy_size(None).unwrap_or(4));
                let huge = bytes > 64 << 20;
                if huge && matches!(data, Data::Exact | Data::Long) {
                    continue;
                }
                let len = match data {
                    Data::Missing => None,
                    Data::Exact => Some(bytes as usize),
                    Data::Short => Some(if huge { 5 } else { bytes as usize / 2 }),
                    Data::Long => Some(bytes as usize + 7),
                };
                let mut image = Image::new_uninit(
                    Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                    TextureDimension::D2,
                    format,
                    RenderAssetUsages::all(),
                );
                image.data = len.map(|n| (0..n).map(|_| (rng.unit() * 256.0) as u8).collect());
                out.push((format!("{format:?} {w}×{h} {data:?}"), image));
            }
        }
    }
    out
}

/// Runs `read` on every image of [`awkward_images`]`(seed)`: each must be read — and
/// then `values` gives the size it read (which must be the image's) and its output's
/// numbers (which must be finite; `values` asserts how many) — or refused with a reason. Never a panic. Prints and returns how many
/// were read and refused; at least one must be read.
pub fn check_image_reader<T>(
    what: &str,
    seed: u32,
    read: impl Fn(&Image) -> Result<T, String>,
    values: impl Fn(&T) -> (Option<UVec2>, Vec<f32>),
) -> (usize, usize) {
    let (mut read_count, mut refused) = (0, 0);
    for (label, image) in awkward_images(seed) {
        match read(&image) {
            Ok(output) => {
                let (size, numbers) = values(&output);
                if let Some(size) = size {
                    assert_eq!(size, image.size(), "{what}, {label}: the size read");
                }
                assert!(
                    numbers.iter().all(|v| v.is_finite()),
                    "{what}, {label}: non-finite values"
                );
                read_count += 1;
            }
            Err(reason) => {
                assert!(!reason.is_empty(), "{what}, {label}: an empty reason");
                refused += 1;
            }
        }
    }
    println!("{what}: {read_count} read, {refused} refused");
    assert!(read_count > 0, "{what}: no image read at all");
    (read_count, refused)
}
