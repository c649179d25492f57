//! Supersampled ground truth for anti-aliasing tests: a render at `factor` × the size
//! per axis, box-filtered in linear light (as an MSAA resolve filters), and error
//! statistics in display values.

use image::RgbaImage;

/// `big` box-filtered `factor` × `factor` in linear light, as display (sRGB) values in
/// [0, 1], row by row.
pub fn box_filter_display(big: &RgbaImage, factor: u32) -> Vec<[f32; 3]> {
    let (w, h) = (big.width() / factor, big.height() / factor);
    let n = (factor * factor) as f32;
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 3];
            for j in 0..factor {
                for i in 0..factor {
                    let p = big.get_pixel(x * factor + i, y * factor + j);
                    for (c, s) in sum.iter_mut().enumerate() {
                        *s += crate::harness::srgb_to_linear(p[c] as f32 / 255.0);
                    }
                }
            }
            out.push(sum.map(|s| crate::harness::linear_to_srgb(s / n)));
        }
    }
    out
}

/// The display values of `img` in [0, 1], row by row.
pub fn display_values(img: &RgbaImage) -> Vec<[f32; 3]> {
    img.pixels()
        .map(|p| [0, 1, 2].map(|c| p[c] as f32 / 255.0))
        .collect()
}

/// Mean and 99th percentile of `values` (sorted in place; 0 for none).
pub fn mean_p99(values: &mut [f32]) -> (f32, f32) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    values.sort_by(f32::total_cmp);
    let mean = values.iter().sum::<f32>() / values.len() as f32;
    let p99 = values[((values.len() as f32 * 0.99) as usize).min(values.len() - 1)];
    (mean, p99)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_filter_averages_in_linear_light() {
        // A 2 × 2 block of black and white averages to linear 0.5: sRGB 0.7354.
        let mut big = RgbaImage::new(2, 2);
        big.put_pixel(0, 0, image::Rgba([255, 255, 255, 255]));
        big.put_pixel(1, 1, image::Rgba([255, 255, 255, 255]));
        let v = box_filter_display(&big, 2)[0][0];
        assert!((v - 0.7354).abs() < 1e-3, "{v}");
        let (mean, p99) = mean_p99(&mut [1.0, 0.0, 2.0]);
        assert!((mean - 1.0).abs() < 1e-6 && p99 == 2.0);
    }
}
