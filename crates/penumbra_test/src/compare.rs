//! Image comparison with explicit tolerances, and failure artefacts.
//!
//! Differences are measured per pixel as the largest absolute channel difference of R, G
//! and B in 8-bit units (alpha is ignored: targets are opaque). A comparison passes when
//! the mean, the 99th percentile and the fraction of pixels above the per-pixel
//! threshold are all within [`Tolerance`].

use image::{Rgba, RgbaImage};
use std::path::PathBuf;

/// Limits for [`compare_rgba8`]. All differences are in 8-bit units (0–255).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// A pixel "differs" when its largest channel difference exceeds this.
    pub per_pixel: u8,
    /// Largest allowed fraction of differing pixels, in [0, 1].
    pub max_differing_fraction: f32,
    /// Largest allowed mean of the per-pixel differences.
    pub max_mean: f32,
    /// Largest allowed 99th percentile of the per-pixel differences.
    pub max_p99: f32,
}

impl Tolerance {
    /// Bit-exact.
    pub const EXACT: Tolerance = Tolerance {
        per_pixel: 0,
        max_differing_fraction: 0.0,
        max_mean: 0.0,
        max_p99: 0.0,
    };

    /// The examples' reference screenshots (`tests/*_example.rs`, `showcase.rs`,
    /// `viewer.rs`): lavapipe is deterministic on one machine; the slack covers other
    /// Mesa/LLVM builds. A wrongly culled caster or a lost occluder moves far more.
    pub const GOLDEN: Tolerance = Tolerance {
        per_pixel: 4,
        max_differing_fraction: 0.005,
        max_mean: 0.5,
        max_p99: 4.0,
    };
}

/// Statistics of one comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comparison {
    /// Mean per-pixel difference.
    pub mean: f32,
    /// 99th percentile of the per-pixel differences.
    pub p99: f32,
    /// Largest per-pixel difference.
    pub max: u8,
    /// Fraction of pixels whose difference exceeds the tolerance's `per_pixel`.
    pub differing_fraction: f32,
    /// Whether every limit of the tolerance holds.
    pub passed: bool,
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mean {:.3}, p99 {:.1}, max {}, differing {:.3} %",
            self.mean,
            self.p99,
            self.max,
            self.differing_fraction * 100.0
        )
    }
}

fn pixel_difference(a: &Rgba<u8>, b: &Rgba<u8>) -> u8 {
    (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0)
}

/// Compares two images of equal size.
///
/// # Panics
/// If the sizes differ (a test bug, not a rendering difference).
pub fn compare_rgba8(actual: &RgbaImage, expected: &RgbaImage, tol: &Tolerance) -> Comparison {
    assert_eq!(
        actual.dimensions(),
        expected.dimensions(),
        "compared images must have the same size"
    );
    let mut histogram = [0u64; 256];
    for (a, e) in actual.pixels().zip(expected.pixels()) {
        histogram[pixel_difference(a, e) as usize] += 1;
    }
    let n: u64 = histogram.iter().sum();
    let n_f = n.max(1) as f64;
    let mean = histogram
        .iter()
        .enumerate()
        .map(|(d, &c)| d as f64 * c as f64)
        .sum::<f64>()
        / n_f;
    // Nearest-rank percentile.
    let rank = ((0.99 * n as f64).ceil() as u64).max(1);
    let mut cumulative = 0;
    let mut p99 = 0;
    for (d, &c) in histogram.iter().enumerate() {
        cumulative += c;
        if cumulative >= rank {
            p99 = d;
            break;
        }
    }
    let max = histogram.iter().rposition(|&c| c > 0).unwrap_or(0) as u8;
    let differing: u64 = histogram[tol.per_pixel as usize + 1..].iter().sum();
    let differing_fraction = (differing as f64 / n_f) as f32;
    let mean = mean as f32;
    let p99 = p99 as f32;
    Comparison {
        mean,
        p99,
        max,
        differing_fraction,
        passed: mean <= tol.max_mean
            && p99 <= tol.max_p99
            && differing_fraction <= tol.max_differing_fraction,
    }
}

/// Where failure artefacts go: `$PENUMBRA_TEST_OUTPUT`, else `target/penumbra_test/` in
/// the workspace.
pub fn output_dir() -> PathBuf {
    std::env::var_os("PENUMBRA_TEST_OUTPUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let crate_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
            let workspace = crate_dir.ancestors().nth(2).unwrap_or(crate_dir);
            workspace.join("target/penumbra_test")
        })
}

/// A visual diff: the expected image dimmed to grey, with pixels over the threshold in
/// red (intensity ∝ difference) and smaller non-zero differences in blue.
pub fn diff_image(actual: &RgbaImage, expected: &RgbaImage, per_pixel: u8) -> RgbaImage {
    RgbaImage::from_fn(actual.width(), actual.height(), |x, y| {
        let (a, e) = (actual.get_pixel(x, y), expected.get_pixel(x, y));
        let d = pixel_difference(a, e);
        let grey = ((e[0] as u16 + e[1] as u16 + e[2] as u16) / 12) as u8;
        let boost = (d as u16 * 4).min(255) as u8;
        if d > per_pixel {
            Rgba([boost.max(128), grey, grey, 255])
        } else if d > 0 {
            Rgba([grey, grey, boost.max(grey), 255])
        } else {
            Rgba([grey, grey, grey, 255])
        }
    })
}

/// Compares and, on failure, writes `<name>.actual.png`, `<name>.expected.png` and
/// `<name>.diff.png` to [`output_dir`], then panics with the statistics and paths.
/// Returns the comparison on success (to print or to check further).
pub fn assert_images_match(
    name: &str,
    actual: &RgbaImage,
    expected: &RgbaImage,
    tol: &Tolerance,
) -> Comparison {
    let cmp = compare_rgba8(actual, expected, tol);
    if cmp.passed {
        return cmp;
    }
    let dir = output_dir();
    let written = std::fs::create_dir_all(&dir).and_then(|()| {
        let save = |suffix: &str, img: &RgbaImage| {
            let path = dir.join(format!("{name}.{suffix}.png"));
            img.save(&path)
                .map_err(std::io::Error::other)
                .map(|()| path)
        };
        Ok([
            save("actual", actual)?,
            save("expected", expected)?,
            save("diff", &diff_image(actual, expected, tol.per_pixel))?,
        ])
    });
    match written {
        Ok(paths) => panic!(
            "{name}: images differ ({cmp}; tolerance {tol:?}).\nWrote {}",
            paths.map(|p| p.display().to_string()).join(", ")
        ),
        Err(e) => {
            panic!("{name}: images differ ({cmp}; tolerance {tol:?}); writing PNGs failed: {e}")
        }
    }
}

/// Panics unless `img` looks like a rendered scene: a spread of luminance (std-dev over
/// 20 of 255) and many distinct colours (over 500).
pub fn assert_not_blank(img: &RgbaImage) {
    let lum: Vec<f32> = img
        .pixels()
        .map(|p| 0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32)
        .collect();
    let mean = lum.iter().sum::<f32>() / lum.len() as f32;
    let std = (lum.iter().map(|l| (l - mean).powi(2)).sum::<f32>() / lum.len() as f32).sqrt();
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| [p[0], p[1], p[2]]).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(std > 20.0, "luminance std-dev {std:.1}: image looks flat");
    assert!(
        colours.len() > 500,
        "only {} distinct colours",
        colours.len()
    );
}

/// Checks `actual` against the golden image at `reference` ([`assert_images_match`],
/// both checked by [`assert_not_blank`]). With `PENUMBRA_BLESS=1` in the environment it
/// writes `actual` as the new reference instead (look at it before committing).
pub fn check_golden(name: &str, actual: &RgbaImage, reference: &std::path::Path, tol: &Tolerance) {
    assert_not_blank(actual);
    if std::env::var("PENUMBRA_BLESS").is_ok_and(|v| v == "1") {
        if let Some(dir) = reference.parent() {
            std::fs::create_dir_all(dir).expect("create the reference folder");
        }
        actual.save(reference).expect("write the reference");
        println!("blessed {}", reference.display());
        return;
    }
    let expected = image::open(reference)
        .unwrap_or_else(|e| panic!("{}: {e} (bless with PENUMBRA_BLESS=1)", reference.display()))
        .to_rgba8();
    assert_not_blank(&expected);
    let cmp = assert_images_match(name, actual, &expected, tol);
    println!("{name} vs reference: {cmp}");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(w: u32, h: u32, v: u8) -> RgbaImage {
        RgbaImage::from_pixel(w, h, Rgba([v, v, v, 255]))
    }

    const LOOSE: Tolerance = Tolerance {
        per_pixel: 2,
        max_differing_fraction: 0.01,
        max_mean: 1.0,
        max_p99: 2.0,
    };

    #[test]
    fn identical_images_pass_exact() {
        let a = flat(8, 8, 100);
        let c = compare_rgba8(&a, &a, &Tolerance::EXACT);
        assert!(c.passed);
        assert_eq!(
            (c.mean, c.p99, c.max, c.differing_fraction),
            (0.0, 0.0, 0, 0.0)
        );
    }

    #[test]
    fn statistics_are_exact_on_a_known_difference() {
        // 100 pixels: one differs by 50 in green only, three by 2.
        let expected = flat(10, 10, 100);
        let mut actual = expected.clone();
        actual.put_pixel(0, 0, Rgba([100, 150, 100, 255]));
        for x in 1..4 {
            actual.put_pixel(x, 0, Rgba([102, 100, 100, 255]));
        }
        let c = compare_rgba8(&actual, &expected, &LOOSE);
        assert_eq!(c.max, 50);
        assert!((c.mean - 0.56).abs() < 1e-6, "{}", c.mean);
        assert_eq!(c.p99, 2.0);
        assert!((c.differing_fraction - 0.01).abs() < 1e-6);
        assert!(c.passed);
        // A second outlier breaks the differing-fraction limit.
        actual.put_pixel(9, 9, Rgba([0, 0, 0, 255]));
        let c = compare_rgba8(&actual, &expected, &LOOSE);
        assert!(!c.passed, "{c}");
    }

    #[test]
    fn alpha_is_ignored() {
        let a = flat(2, 2, 10);
        let mut b = a.clone();
        b.put_pixel(1, 1, Rgba([10, 10, 10, 0]));
        assert!(compare_rgba8(&a, &b, &Tolerance::EXACT).passed);
    }

    #[test]
    fn failure_writes_artefacts_and_names_them() {
        let a = flat(4, 4, 0);
        let b = flat(4, 4, 200);
        let d = diff_image(&a, &b, LOOSE.per_pixel);
        assert_eq!(
            d.get_pixel(0, 0)[0],
            255,
            "large differences are bright red"
        );
        let panic = std::panic::catch_unwind(|| assert_images_match("unit_fail", &a, &b, &LOOSE));
        let message = panic
            .expect_err("mismatch must panic")
            .downcast::<String>()
            .expect("formatted message");
        assert!(message.contains("unit_fail.diff.png"), "{message}");
        for suffix in ["actual", "expected", "diff"] {
            let path = output_dir().join(format!("unit_fail.{suffix}.png"));
            assert!(path.exists(), "{}", path.display());
            std::fs::remove_file(path).ok();
        }
    }
}
