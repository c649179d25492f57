use super::*;

const W: u32 = FENCE_SIZE.0;
const H: u32 = FENCE_SIZE.1;

fn camera() -> PerspectiveCamera {
    fence_camera()
}

/// Mean and 99th percentile of `v`.
fn mean_p99(mut v: Vec<f32>) -> (f32, f32) {
    v.sort_by(f32::total_cmp);
    let mean = v.iter().sum::<f32>() / v.len().max(1) as f32;
    (mean, v[((v.len() as f32 * 0.99) as usize).min(v.len() - 1)])
}

/// Against 4 × 4 supersampling, on the pixels whose samples see different primitives:
/// classified shading is as good as shading every sample and far better than none; the
/// classifier finds every such pixel; elsewhere one shade per pixel is as good as
/// four.
#[test]
fn classified_msaa_matches_per_sample_shading_against_supersampling() {
    let (scene, cam, test) = (fence(), camera(), EdgeTest::default());
    let mut errors = [Vec::new(), Vec::new(), Vec::new()];
    let (mut truth_edges, mut found, mut classified) = (0, 0, 0);
    let mut interior = [Vec::new(), Vec::new(), Vec::new()];
    for y in 0..H {
        for x in 0..W {
            let truth = display(render_truth(&scene, &cam, x, y));
            let px = [Shading::NoAa, Shading::Classified, Shading::PerSample]
                .map(|s| render_pixel(&scene, &cam, x, y, &test, s));
            classified += usize::from(px[1].edge);
            if px[1].primitive_edge {
                truth_edges += 1;
                found += usize::from(px[1].edge);
                for (e, p) in errors.iter_mut().zip(&px) {
                    e.push((display(p.color) - truth).abs().max_element());
                }
            } else {
                for (e, p) in interior.iter_mut().zip(&px) {
                    e.push((display(p.color) - truth).abs().max_element());
                }
            }
        }
    }
    let [none, ours, every] = errors.map(mean_p99);
    let [_, ours_in, every_in] = interior.map(mean_p99);
    let recall = found as f32 / truth_edges as f32;
    let precision = found as f32 / classified as f32;
    eprintln!(
        "{truth_edges} primitive-edge pixels of {}; classifier: {classified} edges, recall \
         {recall:.3}, precision {precision:.3}; edge error (display) mean / p99: no AA \
         {:.4} / {:.4}, classified {:.4} / {:.4}, per sample {:.4} / {:.4}; off edges: \
         classified {:.4} / {:.4}, per sample {:.4} / {:.4}",
        W * H,
        none.0,
        none.1,
        ours.0,
        ours.1,
        every.0,
        every.1,
        ours_in.0,
        ours_in.1,
        every_in.0,
        every_in.1
    );
    assert!(truth_edges > 300, "{truth_edges}");
    assert!(recall >= 0.998, "recall {recall}");
    assert!(
        ours.0 <= 1.1 * every.0 && ours.0 < 0.5 * none.0,
        "{ours:?} {every:?} {none:?}"
    );
    // Off edges one shade per pixel is as good as four (within 0.005).
    assert!(ours_in.0 < every_in.0 + 0.005, "{ours_in:?} {every_in:?}");
}

/// The classifier's rules one at a time.
#[test]
fn the_edge_test_flags_depth_normal_material_and_sky() {
    let s = GSample {
        view_z: 10.0,
        normal: Vec3::Y,
        material: 3,
    };
    let pixel = |f: &dyn Fn(&mut GSample)| {
        let mut other = s;
        f(&mut other);
        GPixel {
            samples: [Some(s), Some(s), Some(other), Some(s)],
            z_slope: 0.05,
        }
    };
    let test = EdgeTest::default();
    assert!(!is_edge(&pixel(&|_| {}), &test));
    // Within the slope plus 10⁻³ of the depth: the same surface.
    assert!(!is_edge(&pixel(&|o| o.view_z += 0.059), &test));
    assert!(is_edge(&pixel(&|o| o.view_z += 0.061), &test));
    assert!(!is_edge(
        &pixel(&|o| o.normal = Vec3::new(0.19, 1.0, 0.0).normalize()),
        &test
    ));
    assert!(is_edge(
        &pixel(&|o| o.normal = Vec3::new(0.21, 1.0, 0.0).normalize()),
        &test
    ));
    assert!(is_edge(&pixel(&|o| o.material = 4), &test));
    let mut sky = pixel(&|_| {});
    sky.samples[3] = None;
    assert!(is_edge(&sky, &test));
    sky.samples = [None; 4];
    assert!(!is_edge(&sky, &test));
    assert_eq!(
        resolve(&[Vec3::ONE, Vec3::ZERO, Vec3::ZERO, Vec3::ONE]),
        Vec3::splat(0.5)
    );
}
