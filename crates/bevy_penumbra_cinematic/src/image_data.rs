//! A check before reading an image texel by texel: Bevy's `Image::get_color_at` slices
//! the image's data without checking its length, so an image whose data is shorter than
//! its size says (a truncated file, a hand-made `Image`) panicked the readers (found by
//! the property tests' `penumbra_test::awkward_images`).

use bevy::image::Image;

/// The image's CPU data holds every texel its size and (uncompressed) format say; an
/// error naming both lengths otherwise, or when there is no CPU data.
pub(crate) fn check_texel_data(image: &Image) -> Result<(), String> {
    let Some(data) = image.data.as_ref() else {
        return Err("no data in the main world (RenderAssetUsages::MAIN_WORLD)".into());
    };
    let format = image.texture_descriptor.format;
    let texel = format
        .block_copy_size(None)
        .filter(|_| format.block_dimensions() == (1, 1));
    if let Some(texel) = texel {
        let needed = image.width() as usize * image.height() as usize * texel as usize;
        if data.len() < needed {
            return Err(format!(
                "{} bytes of data for {}×{} texels of {format:?} ({needed} needed)",
                data.len(),
                image.width(),
                image.height()
            ));
        }
    }
    Ok(())
}
