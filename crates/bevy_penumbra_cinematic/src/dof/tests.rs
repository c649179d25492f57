use super::*;
use bevy::asset::RenderAssetUsages;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};

const FOV: f32 = std::f32::consts::FRAC_PI_4;

#[test]
fn defaults_are_in_range_and_match_bevy() {
    let settings = BokehDepthOfField::default();
    let (lens, rule, problems) = settings.resolve(FOV);
    assert!(problems.is_empty(), "{problems:?}");
    assert_eq!(lens.focal_distance, 10.0);
    assert_eq!(lens.max_coc, 64.0);
    assert_eq!(lens.max_depth, f32::INFINITY);
    assert_eq!(rule, SpriteRule::default());
    // Bevy's `DepthOfField` focal length: ½ sensor / tan(½ fov).
    let f = 0.5 * settings.sensor_height / (0.5 * FOV).tan();
    assert!((lens.focal_length() - f).abs() < 1e-7);
}

#[test]
fn bad_settings_are_clamped_and_named() {
    let bad = BokehDepthOfField {
        focal_distance: f32::NAN,
        aperture_f_stops: -2.0,
        sensor_height: 0.0,
        max_circle_of_confusion_diameter: 1000.0,
        max_depth: f32::NAN,
        min_circle_of_confusion: -1.0,
        merge_coc_tolerance: f32::INFINITY,
        quarter_resolution_coc: 4.0,
        aperture: BokehAperture::Polygon {
            sides: 2,
            rotation: f32::NAN,
        },
        ..default()
    };
    let (lens, rule, problems) = bad.resolve(FOV);
    assert_eq!(problems.len(), 10, "{problems:#?}");
    for name in [
        "focal_distance",
        "aperture_f_stops",
        "sensor_height",
        "max_circle_of_confusion_diameter",
        "max_depth",
        "min_circle_of_confusion",
        "merge_coc_tolerance",
        "quarter_resolution_coc",
        "sides",
        "rotation",
    ] {
        assert!(
            problems.iter().any(|p| p.contains(name)),
            "{name}: {problems:?}"
        );
    }
    assert_eq!(lens.focal_distance, 10.0);
    assert_eq!(lens.f_stops, 1.0);
    assert_eq!(lens.sensor_height, 0.01866);
    assert_eq!(lens.max_coc, 256.0);
    assert_eq!(lens.max_depth, f32::INFINITY);
    assert_eq!(rule.min_coc, 0.0);
    assert_eq!(rule.coc_tolerance, 2.0);
    assert_eq!(rule.quarter_coc, 16.0);
    assert!(lens.coc(1.0, 1080).is_finite());
    // NaN: the default; infinity (every sprite at half resolution) is accepted.
    for (q, want, warned) in [
        (f32::NAN, 32.0, true),
        (f32::INFINITY, f32::INFINITY, false),
    ] {
        let settings = BokehDepthOfField {
            quarter_resolution_coc: q,
            ..default()
        };
        let (_, rule, problems) = settings.resolve(FOV);
        assert_eq!(
            (rule.quarter_coc, problems.len() == 1),
            (want, warned),
            "{q}"
        );
    }
    // A focal plane inside the focal length has no image: twice the focal length.
    let close = BokehDepthOfField {
        focal_distance: 0.001,
        ..default()
    };
    let (lens, _, problems) = close.resolve(FOV);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert_eq!(lens.focal_distance, 10.0);
    let negative = BokehDepthOfField {
        focal_distance: -3.0,
        ..default()
    };
    assert_eq!(negative.resolve(FOV).0.focal_distance, 10.0);
}

fn image(width: u32, height: u32, texel: impl Fn(u32, u32) -> [u8; 4]) -> Image {
    let mut data = Vec::new();
    for y in 0..height {
        for x in 0..width {
            data.extend(texel(x, y));
        }
    }
    Image::new(
        Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    )
}

#[test]
fn aperture_images_are_read_and_bad_ones_rejected() {
    // A white disc on black and an opaque disc on transparency: the same shape.
    let n = 32;
    let inside = |x: u32, y: u32| {
        let d = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) / n as f32 * 2.0 - 1.0;
        d.length() <= 1.0
    };
    let white = image(n, n, |x, y| {
        let v = if inside(x, y) { 255 } else { 0 };
        [v, v, v, 255]
    });
    let alpha = image(n, n, |x, y| {
        [255, 255, 255, if inside(x, y) { 255 } else { 0 }]
    });
    let a = aperture_from_image(&white).expect("a disc");
    let b = aperture_from_image(&alpha).expect("a disc");
    assert_eq!(a.weights(), b.weights());
    assert!(
        (a.mean() - std::f32::consts::FRAC_PI_4).abs() < 0.02,
        "{}",
        a.mean()
    );
    // Half grey: linear luminance, not the sRGB value.
    let grey = aperture_from_image(&image(4, 4, |_, _| [128, 128, 128, 255])).unwrap();
    assert!((grey.mean() - 0.2158).abs() < 1e-3, "{}", grey.mean());

    let empty = aperture_from_image(&image(0, 0, |_, _| [255; 4])).unwrap_err();
    assert!(empty.contains("empty"), "{empty}");
    let not_square = aperture_from_image(&image(8, 4, |_, _| [255; 4])).unwrap_err();
    assert!(not_square.contains("not square"), "{not_square}");
    let blank = aperture_from_image(&image(8, 8, |_, _| [0, 0, 0, 255])).unwrap_err();
    assert!(blank.contains("blank"), "{blank}");
    let huge = aperture_from_image(&image(1025, 1025, |_, _| [255; 4])).unwrap_err();
    assert!(huge.contains("larger"), "{huge}");
    let mut gpu_only = image(8, 8, |_, _| [255; 4]);
    gpu_only.data = None;
    let gpu_only = aperture_from_image(&gpu_only).unwrap_err();
    assert!(gpu_only.contains("CPU copy"), "{gpu_only}");
}

/// A polygon aperture's sides are bounded (four billion sides hung the main world
/// making its image, #47) and its rotation keyed within the turn between two vertices;
/// an animated rotation does not keep a shape per frame (the cache kept every one).
#[test]
fn polygon_apertures_are_bounded_and_not_kept_for_ever() {
    let key = |sides, rotation| ApertureKey::of(&BokehAperture::Polygon { sides, rotation });
    assert_eq!(key(u32::MAX, 0.3), key(MAX_APERTURE_SIDES, 0.3));
    assert_eq!(key(2, 0.3), key(3, 0.3));
    let step = std::f32::consts::TAU / 6.0;
    assert_eq!(key(6, 0.1), key(6, 0.1 + step));
    assert_eq!(key(6, 0.1), key(6, 0.1 - 7.0 * step));
    assert_ne!(key(6, 0.1), key(6, 0.2));
    let huge = BokehDepthOfField {
        aperture: BokehAperture::Polygon {
            sides: u32::MAX,
            rotation: 0.0,
        },
        ..default()
    };
    assert!(huge.problems(FOV).iter().any(|p| p.contains("sides")));

    let mut app = App::new();
    app.init_resource::<Assets<Image>>()
        .add_message::<AssetEvent<Image>>()
        .init_resource::<BokehApertureCache>()
        .add_systems(Update, prepare_bokeh_apertures);
    let camera = app.world_mut().spawn(huge).id();
    let mut ids = HashSet::new();
    for frame in 0..120 {
        if let Some(mut settings) = app.world_mut().get_mut::<BokehDepthOfField>(camera) {
            settings.aperture = BokehAperture::Polygon {
                sides: if frame < 60 { u32::MAX } else { 6 },
                rotation: frame as f32 * 0.02,
            };
        }
        app.update();
        let shape = app
            .world()
            .get::<BokehApertureShape>(camera)
            .expect("a shape");
        ids.insert(shape.id);
        let cached = app.world().resource::<BokehApertureCache>().shapes.len();
        assert!(cached <= 1, "frame {frame}: {cached} shapes cached");
    }
    // The rotation moved every frame: a new shape each time, none kept.
    assert!(ids.len() > 100, "{} shapes", ids.len());
}
