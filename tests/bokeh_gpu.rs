//! Contract tests of scatter bokeh's passes on lavapipe.
//!
//! The sprite pass (`dof/sprites.wgsl`): from a
//! colour image and a reverse-Z depth buffer (a far wall with smooth and noisy patches,
//! the sky, a band in focus, two squares in front of the focal plane, bright dots) it
//! writes the sprites the CPU model (`penumbra_reference::bokeh::{downsample,
//! sprites}`) makes from the same pixels — one per agreeing block, one per
//! out-of-focus pixel elsewhere — in the model's order (each block's four slots, empty
//! ones marked), and counts them; with and without the 1-or-4 rule, and with a sprite
//! buffer too small.
//!
//! The scatter pass (`dof/scatter.wgsl`): the model's sprites of the same image drawn
//! as instanced quads with additive blending into the four `Rgba32Float` layers (near
//! and far, at half resolution and, for sprites of 32 px and more, at quarter
//! resolution) give the model's layers (`scatter_sprites`), for a hexagon and a triangle
//! (which tells near sprites' reflection apart).
//!
//! The composite pass (`dof/composite.wgsl`): from the sharp image, the depth buffer and
//! those layers, the final image equals `composite`'s, and pixels in focus that no near
//! sprite reaches are bit-identical to the input.
//!
//! The passes in a Bevy app, end to end: `crates/bevy_penumbra_cinematic/tests/
//! bokeh_plugin.rs`.

use bevy::math::{Mat4, UVec2, Vec2, Vec3, Vec4};
use penumbra_cinematic_core::dof::{BokehView, Lens, SpriteRule};
use penumbra_cinematic_core::scan::ScanPlan;
use penumbra_reference::bokeh::{
    Aperture, BokehImage, Layers, Sprite, by_layer, composite, downsample, scatter_sprites, sprites,
};
use penumbra_reference::df::f16_to_f32;
use penumbra_shaders::{flatten, flatten_with_defs};
use penumbra_test::multisample::{MsSample, filled_gbuffer};
use penumbra_test::wgpu;
use penumbra_test::{GpuCompute, gpu_or_skip, uniform_bytes};

// The scatter and composite passes' tests.
#[path = "bokeh_gpu/scatter_composite.rs"]
mod scatter_composite;

const SIZE: UVec2 = UVec2::new(96, 64);
const NEAR: f32 = 0.1;

fn lens() -> Lens {
    Lens {
        focal_distance: 3.0,
        f_stops: 0.035,
        sensor_height: 0.01866,
        fov_y: 0.8,
        max_coc: 40.0,
        max_depth: f32::INFINITY,
    }
}

/// Colours are f16 values.
fn image() -> BokehImage {
    let n = (SIZE.x * SIZE.y) as usize;
    // Rounded to f16 precision (11 significant bits), as the GPU's input holds them.
    let q = |v: f32| {
        if v <= 0.0 {
            return 0.0;
        }
        let step = (v.log2().floor() - 10.0).exp2();
        (v / step).round() * step
    };
    let (mut color, mut distance) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for y in 0..SIZE.y {
        for x in 0..SIZE.x {
            let i = y * SIZE.x + x;
            let (c, d) = if y < 6 {
                (Vec3::new(0.25, 0.5, 1.0), f32::INFINITY)
            } else if (61..85).contains(&x) && (21..45).contains(&y) {
                (Vec3::new(1.0, 0.5, 0.125), 1.5)
            } else if (26..40).contains(&x) && (28..42).contains(&y) {
                // Nearer than the focal plane, less blurred than the square.
                (Vec3::new(0.125, 1.0, 0.5), 2.0)
            } else if (11..23).contains(&x) {
                (Vec3::splat(((i * 7919) % 13) as f32 / 8.0), 3.0)
            } else if x > 40 && y > 48 {
                // Noise on the wall: no block agrees.
                (Vec3::splat(((i * 104_729) % 17) as f32 / 8.0), 20.0)
            } else {
                let bright = (x % 23 == 5 && y % 17 == 9) as u32 as f32 * 40.0;
                (
                    Vec3::new(0.5 + x as f32 / 256.0, 0.375, 0.25) + bright,
                    20.0 + 0.02 * y as f32,
                )
            };
            color.push(Vec3::new(q(c.x), q(c.y), q(c.z)));
            distance.push(d);
        }
    }
    BokehImage {
        size: SIZE,
        color,
        distance,
    }
}

/// The view uniform of the test image's camera (infinite reverse-Z, near plane `NEAR`).
fn bokeh_view(lens: &Lens, rule: &SpriteRule, capacity: u32) -> BokehView {
    let clip_from_view =
        Mat4::perspective_infinite_reverse_rh(lens.fov_y, SIZE.x as f32 / SIZE.y as f32, NEAR);
    BokehView::new(lens, rule, clip_from_view.inverse(), SIZE, capacity)
}

/// The image's distances as that camera's `Depth32Float` buffer (the sky at 0).
fn depth_texture(gpu: &GpuCompute, image: &BokehImage) -> wgpu::Texture {
    let depths: Vec<MsSample> = image
        .distance
        .iter()
        .map(|&d| MsSample {
            depth: if d.is_finite() { NEAR / d } else { 0.0 },
            gbuffer: [0; 4],
        })
        .collect();
    filled_gbuffer(gpu, SIZE.x, SIZE.y, 1, &depths).depth
}

/// The model's side of the scatter and composite tests: the test image's sprites under
/// the default rule but for quarter resolution from 16 px, and the uniform that holds
/// them all.
struct Model {
    lens: Lens,
    image: BokehImage,
    rule: SpriteRule,
    sprites: Vec<Sprite>,
    view: BokehView,
}

fn model() -> Model {
    // Sprites of 16 px and more (the square in front, the sky) at quarter resolution.
    let rule = SpriteRule {
        quarter_coc: 16.0,
        ..SpriteRule::default()
    };
    let (lens, image) = (lens(), image());
    let sprites = sprites(&downsample(&image, &lens), &rule);
    let view = bokeh_view(&lens, &rule, sprites.len() as u32);
    Model {
        lens,
        image,
        rule,
        sprites,
        view,
    }
}

struct GpuSprites {
    count: u32,
    sprites: Vec<Sprite>,
}

fn run(
    gpu: &GpuCompute,
    image: &BokehImage,
    lens: &Lens,
    rule: &SpriteRule,
    capacity: u32,
) -> GpuSprites {
    let view = bokeh_view(lens, rule, capacity);
    let depth = depth_texture(gpu, image);
    let halves = |v: f32| half_bits(v).to_le_bytes();
    let color_bytes: Vec<u8> = image
        .color
        .iter()
        .flat_map(|c| [c.x, c.y, c.z, 1.0])
        .flat_map(halves)
        .collect();
    let color = gpu.texture(
        "color",
        wgpu::Extent3d {
            width: SIZE.x,
            height: SIZE.y,
            depth_or_array_layers: 1,
        },
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba16Float,
        8,
        &color_bytes,
    );
    let uniform = gpu.buffer("view", &uniform_bytes(&view), wgpu::BufferUsages::UNIFORM);
    let blocks = (view.half_size + UVec2::ONE) / 2;
    let slot_bytes = u64::from(capacity.max(1)) * 32;
    let block_counts = gpu.zeroed(
        "block_counts",
        u64::from(blocks.x * blocks.y) * 16,
        wgpu::BufferUsages::empty(),
    );
    let slots = gpu.zeroed("slots", slot_bytes, wgpu::BufferUsages::empty());
    let pipeline = gpu.pipeline(
        &flatten("#import penumbra::dof::sprites\n").expect("flattens"),
        "sprites_main",
    );
    let views = [
        color.create_view(&Default::default()),
        depth.create_view(&Default::default()),
    ];
    let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("bokeh_sprites"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            entry(0, uniform.as_entire_binding()),
            entry(1, wgpu::BindingResource::TextureView(&views[0])),
            entry(2, wgpu::BindingResource::TextureView(&views[1])),
            entry(3, block_counts.as_entire_binding()),
            entry(4, slots.as_entire_binding()),
        ],
    });
    gpu.dispatch(
        &pipeline,
        &bind,
        [blocks.x.div_ceil(8), blocks.y.div_ceil(8), 1],
    );
    let list = compact_on_gpu(
        gpu,
        &uniform,
        &block_counts,
        &slots,
        blocks.x * blocks.y,
        capacity,
    );
    let words = |bytes: Vec<u8>| -> Vec<u32> {
        bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let a = words(gpu.read(&list.args, LAYER_DRAWS_BYTES));
    let mut count = 0;
    for l in 0..4 {
        let d = &a[4 * l..4 * l + 4];
        assert_eq!((d[0], d[2], d[3]), (4, 0, 0), "draw {l}'s other arguments");
        // Each layer starts where the ones before it end (later, where the list is full
        // and their draws are capped).
        assert!(a[16 + l] >= count, "layer {l}'s first index");
        assert!(
            a[16 + l] == count || count == capacity,
            "layer {l}'s first index"
        );
        count += d[1];
    }
    let s = words(gpu.read(&list.sprites, slot_bytes));
    let f = |w: u32| f32::from_bits(w);
    GpuSprites {
        count,
        sprites: (0..count as usize)
            .map(|i| {
                let w = &s[8 * i..8 * i + 8];
                Sprite {
                    center: Vec2::new(f(w[0]), f(w[1])),
                    diameter: f(w[2]),
                    weight: f(w[3]),
                    color: Vec3::new(f(w[4]), f(w[5]), f(w[6])),
                    near: f(w[7]) > 0.5,
                }
            })
            .collect(),
    }
}

/// `LayerDraws` (`dof/types.wgsl`): four draws' arguments, the layers' first indices.
const LAYER_DRAWS_BYTES: u64 = 80;

/// The compacted list and its draws' arguments.
struct CompactedList {
    sprites: wgpu::Buffer,
    args: wgpu::Buffer,
}

/// `dof/compact.wgsl`'s three passes, dispatched as the plugin does
/// (`penumbra_cinematic_core::scan::ScanPlan`).
fn compact_on_gpu(
    gpu: &GpuCompute,
    uniform: &wgpu::Buffer,
    block_counts: &wgpu::Buffer,
    slots: &wgpu::Buffer,
    blocks: u32,
    capacity: u32,
) -> CompactedList {
    let plan = ScanPlan::new(blocks);
    let list = CompactedList {
        sprites: gpu.zeroed(
            "sprites",
            u64::from(capacity.max(1)) * 32,
            wgpu::BufferUsages::empty(),
        ),
        args: gpu.zeroed("args", LAYER_DRAWS_BYTES, wgpu::BufferUsages::INDIRECT),
    };
    let group_sums = gpu.zeroed(
        "group_sums",
        u64::from(plan.group_sums_len()) * 16,
        wgpu::BufferUsages::empty(),
    );
    let source = flatten("#import penumbra::dof::compact\n").expect("flattens");
    let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
    let passes = [
        ("reduce_main", plan.workgroups()[0]),
        ("scan_groups_main", plan.workgroups()[1]),
        ("compact_main", plan.workgroups()[2]),
    ];
    for (name, groups) in passes {
        let pipeline = gpu.pipeline(&source, name);
        let mut entries = vec![
            entry(0, uniform.as_entire_binding()),
            entry(5, group_sums.as_entire_binding()),
        ];
        if name != "scan_groups_main" {
            entries.push(entry(1, block_counts.as_entire_binding()));
        }
        if name != "reduce_main" {
            entries.push(entry(4, list.args.as_entire_binding()));
        }
        if name == "compact_main" {
            entries.push(entry(2, slots.as_entire_binding()));
            entries.push(entry(3, list.sprites.as_entire_binding()));
        }
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(name),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        gpu.dispatch(&pipeline, &bind, [groups, 1, 1]);
    }
    list
}

/// `v` (an f16 value, normal or zero) as f16 bits.
fn half_bits(v: f32) -> u16 {
    if v == 0.0 {
        return 0;
    }
    let b = v.to_bits();
    let exponent = ((b >> 23) & 0xff) as i32 - 127 + 15;
    (((b >> 16) & 0x8000) | ((exponent as u32) << 10) | ((b >> 13) & 0x3ff)) as u16
}

#[test]
fn sprite_pass_matches_the_model() {
    if !gpu_or_skip("sprite_pass_matches_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let lens = lens();
    let image = image();
    let half = downsample(&image, &lens);
    // Default thresholds (but quarter resolution from 16 px, so that every layer holds
    // sprites), no merging, and thresholds so loose that only the side of the focal plane
    // and focus itself keep blocks apart.
    let base = model().rule;
    let loose = SpriteRule {
        coc_tolerance: 1e3,
        color_tolerance: 1e3,
        depth_tolerance: 1e3,
        ..base
    };
    let unmerged = SpriteRule {
        merge: false,
        ..base
    };
    let blocks_only = SpriteRule {
        merge_groups: false,
        ..base
    };
    for (name, rule) in [
        ("default", base),
        ("unmerged", unmerged),
        ("blocks only", blocks_only),
        ("loose", loose),
    ] {
        let merge = rule.merge;
        let (want, first) = by_layer(&sprites(&half, &rule), rule.quarter_diameter());
        let got = run(&gpu, &image, &lens, &rule, 4096);
        let blocks = want.iter().filter(|s| s.weight > 1.0).count();
        let groups = want.iter().filter(|s| s.weight > 4.0).count();
        let near = want.iter().filter(|s| s.near).count();
        eprintln!(
            "{name}: {} sprites on the GPU, {} in the model ({blocks} blocks, {groups} of \
             them groups, {near} near)",
            got.count,
            want.len()
        );
        eprintln!("  layers start at {first:?}");
        assert!(
            want.len() > 200 && near >= 36 && (blocks > 100) == merge,
            "{name}"
        );
        assert_eq!(groups > 10, merge && rule.merge_groups, "{name}: groups");
        assert!(
            first.windows(2).all(|w| w[0] < w[1]) && first[3] < want.len(),
            "{name}: every layer holds sprites: {first:?}"
        );
        assert_eq!(got.count as usize, want.len(), "{name}: sprite count");
        // Layer by layer, in slot order: the model's order, whatever the threads' timing.
        let got = got.sprites;
        assert_eq!(got.len(), want.len(), "{name}: sprites stored");
        let mut worst = (0.0f32, 0.0f32);
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((g.center, g.weight, g.near), (w.center, w.weight, w.near));
            worst.0 = worst.0.max((g.diameter - w.diameter).abs() / w.diameter);
            worst.1 = worst
                .1
                .max((g.color - w.color).abs().max_element() / w.color.max_element().max(1.0));
        }
        eprintln!(
            "  largest relative difference: diameter {:.2e}, colour {:.2e}",
            worst.0, worst.1
        );
        // The depth round trip (1/z through the projection) and f16 colour storage.
        assert!(worst.0 < 1e-3 && worst.1 < 1e-3, "{name}: {worst:?}");
    }
    // Buffers too small (512 slots, 128 blocks): the draws are capped at 512 sprites in
    // all, the first 128 blocks' sprites are listed as the model's, nothing is written
    // past the buffers (later blocks' places stay empty).
    let (want, _) = by_layer(&sprites(&half, &base), base.quarter_diameter());
    assert!(want.len() > 512);
    let got = run(&gpu, &image, &lens, &base, 512);
    assert_eq!(got.count, 512);
    let blocks_x = half.size.x.div_ceil(2);
    let stored_block = |s: &Sprite| {
        // The first texel of the square it stands for, then its block.
        let b = ((s.center - 0.5 * s.spread() - 0.5) / 2.0).floor();
        (b.y as u32) * blocks_x + (b.x as u32) < 128
    };
    let stored = want.iter().take(512).filter(|s| stored_block(s)).count();
    assert!(stored > 0, "the first blocks hold sprites");
    for (i, (g, w)) in got.sprites.iter().zip(&want).enumerate() {
        if stored_block(w) {
            assert_eq!((g.center, g.weight, g.near), (w.center, w.weight, w.near));
        } else {
            assert_eq!(g.weight, 0.0, "{i}: past the stored blocks");
        }
    }
}

/// The compaction over many workgroups (a 1000 × 600 half-resolution view: 150,000
/// blocks, 147 groups of 1,024): the list is the slots' live sprites layer by layer, in
/// slot order within each, with no gap and none lost, and each layer's draw count is
/// its own — as a sequential scan lists them. Random occupancy and layers, runs of empty
/// blocks across group boundaries.
#[test]
fn compaction_over_many_workgroups_keeps_slot_order() {
    if !gpu_or_skip("compaction_over_many_workgroups_keeps_slot_order") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let half = UVec2::new(1000, 600);
    let blocks = (half.x / 2) * (half.y / 2);
    let capacity = 4 * blocks;
    let plan = ScanPlan::new(blocks);
    assert!(plan.groups > 100, "{plan:?}");
    let mut seed = 0x2545_f491u32;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed
    };
    let mut slot_words = vec![0f32; 8 * capacity as usize];
    let mut counts = vec![0u32; 4 * blocks as usize];
    let mut layers: [Vec<u32>; 4] = Default::default();
    for b in 0..blocks {
        // Every tenth stretch of 3,000 blocks is empty (crossing group boundaries).
        let empty = (b / 3000) % 10 == 3;
        for k in 0..4 {
            let slot = 4 * b + k;
            if !empty && next() % 3 == 0 {
                // A random layer: near or far, half or quarter resolution.
                let (near, quarter) = (next() % 2 == 0, next() % 2 == 0);
                let layer = usize::from(!near) + 2 * usize::from(quarter);
                let w = &mut slot_words[8 * slot as usize..8 * slot as usize + 8];
                w[0] = slot as f32;
                w[2] = if quarter { 100.0 } else { 1.0 };
                w[3] = 1.0 + (slot % 4) as f32;
                w[7] = if near { 1.0 } else { 0.0 };
                counts[4 * b as usize + layer] += 1;
                layers[layer].push(slot);
            }
        }
    }
    let want: Vec<u32> = layers.concat();
    let full = half * 2;
    let lens = lens();
    let rule = SpriteRule::default();
    let clip_from_view =
        Mat4::perspective_infinite_reverse_rh(lens.fov_y, full.x as f32 / full.y as f32, NEAR);
    let view = BokehView::new(&lens, &rule, clip_from_view.inverse(), full, capacity);
    assert_eq!(view.half_size, half);
    let uniform = gpu.buffer("view", &uniform_bytes(&view), wgpu::BufferUsages::UNIFORM);
    let bytes = |w: &[u32]| w.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    let block_counts = gpu.buffer("block_counts", &bytes(&counts), wgpu::BufferUsages::empty());
    let slot_bits: Vec<u32> = slot_words.iter().map(|f| f.to_bits()).collect();
    let slots = gpu.buffer("slots", &bytes(&slot_bits), wgpu::BufferUsages::empty());
    let list = compact_on_gpu(&gpu, &uniform, &block_counts, &slots, blocks, capacity);
    let words = |b: Vec<u8>| -> Vec<u32> {
        b.chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let args = words(gpu.read(&list.args, LAYER_DRAWS_BYTES));
    let listed_count: u32 = (0..4).map(|l| args[4 * l + 1]).sum();
    eprintln!(
        "{} sprites in {blocks} blocks, {} groups: {listed_count} listed",
        want.len(),
        plan.groups,
    );
    for (l, layer) in layers.iter().enumerate() {
        assert_eq!(
            args[4 * l + 1] as usize,
            layer.len(),
            "layer {l}'s draw count"
        );
    }
    let listed = words(gpu.read(&list.sprites, u64::from(capacity) * 32));
    let got: Vec<u32> = (0..want.len())
        .map(|i| f32::from_bits(listed[8 * i]) as u32)
        .collect();
    let first_wrong = got.iter().zip(&want).position(|(g, w)| g != w);
    assert_eq!(
        first_wrong, None,
        "the first sprite out of layer and slot order"
    );
    // Nothing past the list.
    assert!(listed[8 * want.len()..].iter().all(|&w| w == 0));
}
