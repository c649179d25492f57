//! The examples' character: a head's short hair and beard as hair strands (a Fibonacci
//! lattice of roots over an ellipsoid scalp and jaw, each strand combed down and kept off
//! the skin) and an atlas of hair clumps. Used by `hair` and `samaritan`.

use bevy::asset::RenderAssetUsages;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use penumbra::cinematic::hair::Strand;

/// The head's semi-axes, metres (an ellipsoid).
pub const HEAD: Vec3 = Vec3::new(0.078, 0.105, 0.092);
/// Columns of the atlas.
pub const SLOTS: u32 = 4;

/// The head's parts as ellipsoids of skin: centre (from the head's centre) and
/// semi-axes of the head, the nose, the ears and the neck.
pub const HEAD_PARTS: [(Vec3, Vec3); 5] = [
    (Vec3::ZERO, HEAD),
    (Vec3::new(0.0, -0.01, 0.092), Vec3::new(0.014, 0.026, 0.018)),
    (Vec3::new(0.079, 0.0, -0.005), Vec3::new(0.01, 0.028, 0.017)),
    (
        Vec3::new(-0.079, 0.0, -0.005),
        Vec3::new(0.01, 0.028, 0.017),
    ),
    (Vec3::new(0.0, -0.16, -0.015), Vec3::new(0.052, 0.09, 0.052)),
];

/// A deterministic value in [0, 1) for `(i, salt)`.
fn hash(i: u32, salt: u32) -> f32 {
    let mut h = i.wrapping_mul(0x9e37_79b9) ^ salt.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Direction `i` of `n` spread evenly over the sphere (a Fibonacci lattice).
fn lattice(i: u32, n: u32) -> Vec3 {
    let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
    let r = (1.0 - y * y).max(0.0).sqrt();
    let phi = i as f32 * 2.399_963;
    Vec3::new(r * phi.cos(), y, r * phi.sin())
}

/// Grows a strand from the head's surface in direction `d` (unit, from the centre):
/// it leaves the skin at a low angle and lies along `comb` (projected onto the scalp),
/// `segments` steps of `length / segments`, kept at least 2 mm off the skin.
fn grow(
    d: Vec3,
    length: f32,
    segments: u32,
    comb: Vec3,
    lift: f32,
    width: f32,
    slot: u32,
) -> Strand {
    let root = d * HEAD * 0.985;
    let normal = (d / HEAD).normalize();
    let along = (comb - normal * normal.dot(comb)).normalize_or(comb);
    let mut points = vec![root];
    let mut dir = (normal * lift + along).normalize();
    let mut p = root;
    for _ in 0..segments {
        p += dir * (length / segments as f32);
        let r = (p / HEAD).length();
        let floor = 1.0 + 0.002 / HEAD.min_element();
        if r < floor {
            p *= floor / r;
        }
        points.push(p);
        dir = (dir + comb * 0.4).normalize();
    }
    Strand {
        points,
        width,
        slot,
    }
}

/// Short hair over the scalp and a beard over the jaw, head-centred metres.
pub fn head_strands() -> Vec<Strand> {
    let mut strands = Vec::new();
    let n = 9000;
    for i in 0..n {
        let d = lattice(i, n);
        let slot = (hash(i, 7) * SLOTS as f32) as u32;
        // Scalp: the crown, and the back and sides down to the nape, above the ears.
        let scalp = d.y > 0.42 || (d.z < 0.2 && d.y > -0.25 + 0.5 * d.z.max(0.0));
        // Beard: the jaw and chin, below the cheekbones.
        let beard = d.z > 0.3 && d.y < -0.2 && d.y > -0.92 && d.x.abs() < 0.9;
        if scalp {
            let length = 0.035 + 0.02 * hash(i, 1);
            let comb = Vec3::new(0.3 * (hash(i, 2) - 0.5), -0.8, -0.6).normalize();
            strands.push(grow(d, length, 4, comb, 0.5, 0.0016, slot));
        } else if beard && hash(i, 3) < 0.8 {
            let length = 0.012 + 0.008 * hash(i, 4);
            let comb = Vec3::new(0.2 * (hash(i, 5) - 0.5), -1.0, 0.15).normalize();
            strands.push(grow(d, length, 2, comb, 0.8, 0.0013, slot));
        }
    }
    strands
}

/// The hair atlas: `SLOTS` columns of 16 × 64 texels, each a clump of three or four
/// hairs (alpha: narrow profiles across, thinning towards the tip), tinted slightly.
pub fn hair_atlas() -> Image {
    let (w, h) = (16 * SLOTS, 64);
    let mut data = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        let u = (y as f32 + 0.5) / h as f32;
        for x in 0..w {
            let slot = x / 16;
            let v = ((x % 16) as f32 + 0.5) / 16.0;
            let hairs: &[f32] = match slot {
                0 => &[0.2, 0.45, 0.75],
                1 => &[0.15, 0.38, 0.6, 0.85],
                2 => &[0.25, 0.5, 0.8],
                _ => &[0.12, 0.35, 0.62, 0.88],
            };
            // Each hair's half-width across the strip thins to a third at the tip.
            let half = 0.11 * (1.0 - 0.66 * u);
            let alpha = hairs
                .iter()
                .map(|c| (1.0 - ((v - c) / half).powi(2)).max(0.0))
                .fold(0.0f32, f32::max);
            let tint = 0.85 + 0.15 * hash(slot, 11);
            let t = |c: f32| (c * tint * 255.0) as u8;
            data.extend([t(1.0), t(0.95), t(0.9), (alpha.sqrt() * 255.0) as u8]);
        }
    }
    Image::new(
        Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8Unorm,
        RenderAssetUsages::default(),
    )
}
