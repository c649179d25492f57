//! The shadow passes driven through wgpu directly, and their inputs: a known scene (a
//! ground plane, a sphere, a rotated non-uniformly scaled box, a capsule, a baked torus
//! SDF in the atlas, a small sphere high up), its depth buffer and G-buffer normals
//! sphere-traced on the CPU through the same objects, the CPU model's mask. Shared by
//! the contract tests of `shadow_mask_gpu.rs`.

#![allow(dead_code, reason = "not every test binary uses every helper")]

use glam::{Affine3A, Mat3, Mat4, Quat, UVec2, UVec3, UVec4, Vec2, Vec3};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::cull::{CameraOrigin, Frustum, cull_view_words, grid_64};
use penumbra_df_core::heightfield::{Heightfield, HeightfieldTexture};
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode, flags};
use penumbra_df_core::shadow::{
    SHADOW_GRID_BYTES, SHADOW_GRID_MAX_CELLS, ShadowLight, ShadowLightKind, TRACE_FACE_NORMALS,
    TRACE_GBUFFER_NORMALS, face_normal_trusted, grid_view_words, trace_view_words, words_to_bytes,
};
use penumbra_reference::df::{Atlas, object_distance};
use penumbra_reference::shadow_mask::{
    pack_gbuffer_normal, pixel_visibility_with_terrain, position_from_depth,
    receiver_normal_in_depth, unpack_gbuffer_normal,
};
use penumbra_sdf::{BakeSettings, bake, shapes};
use penumbra_shaders::flatten;
use penumbra_test::GpuCompute;
use penumbra_test::wgpu::{self, BufferUsages};

#[path = "shadow_layouts.rs"]
mod layouts;

#[allow(unused_imports, reason = "not every test binary uses every helper")]
pub use layouts::{SampleTrace, UNWRITTEN, sample_trace};
use layouts::{float_entry, mask_entry, trace_layout, uniform_entry};

pub const WIDTH: u32 = 124;
pub const HEIGHT: u32 = 90;
pub const EYE: Vec3 = Vec3::new(0.9, 2.6, 3.6);

pub struct Scene {
    pub records: Vec<ObjectRecord>,
    pub atlas: Atlas,
    pub atlas_size: UVec3,
    pub atlas_bits: Vec<u16>,
    /// Terrains (none unless a test adds [`hills`]).
    pub terrain: HeightfieldTexture,
}

pub fn scene(offset: Vec3) -> Scene {
    scene_with(offset, 36, false)
}

/// [`scene`] with its torus baked at 72 samples and placed as sparse bricks
/// (`penumbra_sdf::bricks`): its pool and coarse grid in the atlas above the dense
/// torus, its entries in the brick table.
pub fn bricked_scene(offset: Vec3) -> Scene {
    scene_with(offset, 72, true)
}

/// [`scene`] with its torus baked at `samples` along its longest axis, dense or placed
/// as sparse bricks.
pub fn scene_with(offset: Vec3, samples: u32, bricked: bool) -> Scene {
    scene_with_torus(offset, samples, bricked, Some(0.4))
}

/// [`scene_with`], the torus letting `ao_transmission` of the sky through in DFAO
/// (`None`: it occludes, so that the global field composes it too).
pub fn scene_with_torus(
    offset: Vec3,
    samples: u32,
    bricked: bool,
    ao_transmission: Option<f32>,
) -> Scene {
    let torus = bake(
        &shapes::torus(0.5, 0.18, 48, 24),
        &BakeSettings::longest_axis(samples),
        None,
    )
    .expect("torus bakes")
    .volume;
    let dims = torus.dims;
    let bits: Vec<u16> = torus.data.iter().map(|h| h.to_bits()).collect();
    let sparse = penumbra_sdf::bricks::BrickedVolume::from_volume(
        &torus,
        penumbra_sdf::bricks::DEFAULT_BAND_VOXELS,
    );
    let round8 = |v: u32| v.div_ceil(8) * 8;
    let pool = penumbra_df_core::bricks::pool_blocks(sparse.stored() as u32) * 8;
    let pool_origin = UVec3::new(0, 0, round8(dims.z));
    let coarse_origin = UVec3::new(0, 0, pool_origin.z + pool.z);
    let size = if bricked {
        dims.max(pool)
            .max(sparse.coarse_dims())
            .with_z(coarse_origin.z + sparse.coarse_dims().z)
    } else {
        dims
    };
    let mut atlas = Atlas::new(size);
    atlas.write(UVec3::ZERO, dims, &bits);
    let torus_shape = if bricked {
        let table_offset = atlas
            .place_bricked(&sparse, pool_origin, coarse_origin)
            .expect("fits");
        CasterShape::BrickedVolume {
            table_offset,
            dims,
            local_origin: torus.origin.as_vec3(),
            voxel_size: torus.voxel_size,
            margin: torus.margin,
        }
    } else {
        CasterShape::Volume {
            region: AtlasRegion {
                origin: UVec3::ZERO,
                dims,
            },
            local_origin: torus.origin.as_vec3(),
            voxel_size: torus.voxel_size,
            margin: torus.margin,
        }
    };
    // The atlas's texels came from f16 samples: converting back is exact.
    let bits: Vec<u16> = atlas
        .texels
        .iter()
        .map(|&t| penumbra_sdf::volume::f16::from_f32(t).to_bits())
        .collect();
    let live = flags::LIVE | flags::CASTS_SHADOWS | flags::CASTS_OCCLUSION | flags::VISIBLE;
    let at = |p: Vec3| Affine3A::from_translation(p + offset);
    let descs = [
        ObjectDesc {
            world_from_local: at(Vec3::ZERO),
            shape: CasterShape::Plane,
            flags: live | flags::UNBOUNDED,
        },
        ObjectDesc {
            world_from_local: at(Vec3::new(-1.3, 0.6, -0.4)),
            shape: CasterShape::Sphere { radius: 0.6 },
            flags: live,
        },
        ObjectDesc {
            world_from_local: Affine3A::from_scale_rotation_translation(
                Vec3::new(1.4, 0.8, 1.0),
                Quat::from_rotation_y(0.6) * Quat::from_rotation_x(0.3),
                Vec3::new(1.4, 0.6, -0.6) + offset,
            ),
            shape: CasterShape::Cuboid {
                half_extents: Vec3::splat(0.45),
            },
            flags: live,
        },
        ObjectDesc {
            world_from_local: Affine3A::from_rotation_translation(
                Quat::from_rotation_z(0.9),
                Vec3::new(0.2, 0.9, -1.9) + offset,
            ),
            shape: CasterShape::Capsule {
                radius: 0.22,
                half_length: 0.6,
            },
            flags: live,
        },
        ObjectDesc {
            world_from_local: Affine3A::from_rotation_translation(
                Quat::from_rotation_x(1.2),
                Vec3::new(0.1, 0.75, 0.6) + offset,
            ),
            shape: torus_shape,
            // Foliage-like: lets 40 % of the sky through in DFAO (shadows ignore it).
            flags: live | flags::TWO_SIDED | ao_transmission.map_or(0, flags::ao_transmission_bits),
        },
        ObjectDesc {
            world_from_local: at(Vec3::new(0.9, 2.6, 1.0)),
            shape: CasterShape::Sphere { radius: 0.06 },
            flags: live,
        },
        // Off screen toward the sun: its shadow falls into the view (the light cull must
        // keep it).
        ObjectDesc {
            world_from_local: at(Vec3::new(4.0, 3.8, 1.6)),
            shape: CasterShape::Sphere { radius: 0.5 },
            flags: live,
        },
        // Off screen, shadowing nothing visible, and beyond the sphere light's range:
        // the light cull drops it.
        ObjectDesc {
            world_from_local: at(Vec3::new(-25.0, 1.0, 25.0)),
            shape: CasterShape::Cuboid {
                half_extents: Vec3::splat(1.0),
            },
            flags: live,
        },
        // Does not cast shadows.
        ObjectDesc {
            world_from_local: at(Vec3::new(-0.6, 0.3, 1.0)),
            shape: CasterShape::Sphere { radius: 0.3 },
            flags: flags::LIVE | flags::VISIBLE,
        },
    ];
    Scene {
        records: descs.iter().map(|d| encode(d).expect("encodes")).collect(),
        atlas,
        atlas_size: size,
        atlas_bits: bits,
        terrain: HeightfieldTexture::default(),
    }
}

pub struct View {
    pub camera: CameraOrigin,
    pub clip_from_view: Mat4,
    pub view_from_clip: Mat4,
    pub world_from_view: Mat3,
    pub frustum: Frustum,
    /// Reverse-Z depth per pixel, rows from the top; 0 where the ray escapes.
    pub depth: Vec<f32>,
    /// G-buffer normal words (Bevy's encoding) per pixel: the scene's distance gradient
    /// at the hit, facing the camera.
    pub normals: Vec<u32>,
}

impl View {
    /// The normal the pass reads at pixel `i`.
    pub fn normal(&self, i: usize) -> Vec3 {
        unpack_gbuffer_normal(self.normals[i])
    }
}

/// A camera 4 m from the scene, and the depth buffer sphere-traced through it.
pub fn view(scene: &Scene, offset: Vec3) -> View {
    let eye = EYE + offset;
    let view_from_world = Mat4::look_at_rh(eye, Vec3::new(0.0, 0.3, -0.6) + offset, Vec3::Y);
    let world_from_view = Mat3::from_mat4(view_from_world).transpose();
    let clip_from_view =
        Mat4::perspective_infinite_reverse_rh(0.9, WIDTH as f32 / HEIGHT as f32, 0.1);
    let view_from_clip = clip_from_view.inverse();
    let camera = CameraOrigin::at(eye).expect("finite");
    let relative_view = Mat4::from_mat3(world_from_view.transpose());
    let frustum = Frustum::from_clip_from_relative(clip_from_view * relative_view);
    let mut depth = vec![0.0f32; (WIDTH * HEIGHT) as usize];
    let mut normals = vec![0u32; (WIDTH * HEIGHT) as usize];
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let screen = Vec2::new(x as f32, y as f32) + 0.5;
            let (d, n) = march(scene, &camera, clip_from_view, world_from_view, screen);
            depth[(y * WIDTH + x) as usize] = d;
            normals[(y * WIDTH + x) as usize] = n;
        }
    }
    View {
        camera,
        clip_from_view,
        view_from_clip,
        world_from_view,
        frustum,
        depth,
        normals,
    }
}

/// The reverse-Z depth (0 where the ray escapes) and G-buffer normal word at
/// frame-buffer point `screen` (pixels from the top-left corner): the scene
/// sphere-traced along the ray through it; the normal is the scene's distance gradient
/// at the hit, facing the camera.
pub fn march(
    scene: &Scene,
    camera: &CameraOrigin,
    clip_from_view: Mat4,
    world_from_view: Mat3,
    screen: Vec2,
) -> (f32, u32) {
    let distance = |p: Vec3| {
        scene
            .records
            .iter()
            .map(|r| object_distance(r, p, camera, &scene.atlas))
            .fold(f32::INFINITY, f32::min)
    };
    // The point's ray: the far point of its NDC through the camera.
    let uv = screen / Vec2::new(WIDTH as f32, HEIGHT as f32);
    let ndc = glam::Vec4::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.5, 1.0);
    let v = clip_from_view.inverse() * ndc;
    let dir = (world_from_view * (v.truncate() / v.w)).normalize();
    let mut t = 0.1;
    for _ in 0..256 {
        let p = dir * t;
        let d = distance(p);
        if d < 1e-4 {
            let view_p = world_from_view.transpose() * p;
            let clip = clip_from_view * view_p.extend(1.0);
            let e = 1e-3;
            let g = Vec3::new(
                distance(p + Vec3::X * e) - distance(p - Vec3::X * e),
                distance(p + Vec3::Y * e) - distance(p - Vec3::Y * e),
                distance(p + Vec3::Z * e) - distance(p - Vec3::Z * e),
            )
            .normalize_or(-dir);
            let n = if g.dot(dir) > 0.0 { -g } else { g };
            return (clip.z / clip.w, pack_gbuffer_normal(n));
        }
        t += d;
        if t > 60.0 {
            break;
        }
    }
    (0.0, 0)
}

pub fn reference_mask(scene: &Scene, view: &View, light: &ShadowLight) -> Vec<f32> {
    reference_mask_by(scene, view, light, true)
}

/// [`reference_mask`], with the depth buffer's face normal (`ReceiverNormal::face`)
/// or without it (`face: false`: what the other rules give).
pub fn reference_mask_by(scene: &Scene, view: &View, light: &ShadowLight, face: bool) -> Vec<f32> {
    reference_mask_with(scene, view, light, face, None)
}

/// [`reference_mask`] with each pixel's triangle normal from the face-normal prepass
/// where its depth is trusted (`ReceiverNormal::facet`, `face_normal_trusted`), as
/// [`MaskOptions::facets`] gives the pass.
pub fn reference_mask_with_facets(
    scene: &Scene,
    view: &View,
    light: &ShadowLight,
    (facets, depths): (&[Vec3], &[f32]),
) -> Vec<f32> {
    let trusted: Vec<Vec3> = facets
        .iter()
        .zip(depths)
        .zip(&view.depth)
        .map(|((&f, &fd), &d)| {
            if face_normal_trusted(f != Vec3::ZERO, fd, d) {
                f
            } else {
                Vec3::ZERO
            }
        })
        .collect();
    reference_mask_with(scene, view, light, true, Some(&trusted))
}

fn reference_mask_with(
    scene: &Scene,
    view: &View,
    light: &ShadowLight,
    face: bool,
    facets: Option<&[Vec3]>,
) -> Vec<f32> {
    let size = Vec2::new(WIDTH as f32, HEIGHT as f32);
    (0..WIDTH * HEIGHT)
        .map(|i| {
            let depth = view.depth[i as usize];
            if depth <= 0.0 {
                return 1.0;
            }
            let pixel = Vec2::new((i % WIDTH) as f32, (i / WIDTH) as f32);
            let p = position_from_depth(
                view.view_from_clip,
                view.world_from_view,
                size,
                pixel,
                depth,
            );
            let n = view.normal(i as usize);
            // The pass's tests of the G-buffer normal against the depth buffer about it.
            let mut receiver = receiver_normal_in_depth(
                &view.depth,
                WIDTH,
                HEIGHT,
                (i % WIDTH, i / WIDTH),
                n,
                |x, y, d| {
                    let pixel = Vec2::new(x as f32, y as f32);
                    position_from_depth(view.view_from_clip, view.world_from_view, size, pixel, d)
                },
            );
            if !face {
                receiver.face = Vec3::ZERO;
            }
            if let Some(facets) = facets {
                receiver.facet = facets[i as usize];
            }
            pixel_visibility_with_terrain(
                &scene.records,
                &scene.atlas,
                &view.camera,
                p,
                receiver,
                light,
                &scene.terrain,
            )
            .0
        })
        .collect()
}

pub struct Passes {
    pub cull: wgpu::ComputePipeline,
    pub trace: wgpu::ComputePipeline,
    pub trace_layout: wgpu::BindGroupLayout,
    pub upsample: wgpu::ComputePipeline,
    pub upsample_layout: wgpu::BindGroupLayout,
    /// The light-space grid's passes: reset, bounds, count, scan, fill.
    pub grid: [wgpu::ComputePipeline; 5],
}

pub fn passes(gpu: &GpuCompute) -> Passes {
    let cull = gpu.pipeline(
        &flatten("#import penumbra::df::shadow_cull\n").unwrap(),
        "cull",
    );
    let trace_layout = trace_layout(gpu, false);
    let trace = gpu.pipeline_with_layouts(
        &flatten("#import penumbra::df::shadow_trace\n").unwrap(),
        "trace",
        &[&trace_layout],
    );
    let upsample_layout = gpu
        .device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow_upsample"),
            entries: &[
                float_entry(0, wgpu::TextureViewDimension::D2),
                float_entry(1, wgpu::TextureViewDimension::D2),
                uniform_entry(2),
                mask_entry(3),
            ],
        });
    let upsample = gpu.pipeline_with_layouts(
        &flatten("#import penumbra::df::shadow_upsample\n").unwrap(),
        "upsample",
        &[&upsample_layout],
    );
    let grid_source = flatten("#import penumbra::df::shadow_grid_build\n").unwrap();
    let grid = [
        "grid_reset",
        "grid_bounds",
        "grid_count",
        "grid_scan",
        "grid_fill",
    ]
    .map(|entry| gpu.pipeline(&grid_source, entry));
    Passes {
        cull,
        trace,
        trace_layout,
        upsample,
        upsample_layout,
        grid,
    }
}

/// How [`gpu_mask_at`] runs the passes.
#[derive(Clone, Copy)]
pub struct MaskOptions<'a> {
    /// 1 full, 2 half resolution.
    pub stride: u32,
    /// Directional lights use the light-space grid (the plugin's way) or the plain list.
    pub use_grid: bool,
    /// Also time 5 more trace dispatches.
    pub time: bool,
    /// Trace the samples of the pixels classed per sample instead, into a mask twice
    /// the view's size (texels of other pixels stay [`UNWRITTEN`]).
    pub samples: Option<&'a SampleTrace>,
    /// The face-normal prepass's normal per pixel (zero: none drawn) and its reverse-Z
    /// depth; `None`: no prepass.
    pub facets: Option<(&'a [Vec3], &'a [f32])>,
}

impl Default for MaskOptions<'_> {
    fn default() -> Self {
        MaskOptions {
            stride: 1,
            use_grid: true,
            time: false,
            samples: None,
            facets: None,
        }
    }
}

/// What [`gpu_mask_at`] produced.
pub struct MaskRun {
    pub values: Vec<f32>,
    /// Objects the light cull kept.
    pub kept: u32,
    pub texture: wgpu::Texture,
    /// The grid built, when used: (large casters, listed items).
    pub grid: Option<(u32, u32)>,
    /// Trace times, milliseconds (with `time`).
    pub times: Vec<f64>,
}

/// Runs the light cull and the mask pass: (mask, number of objects the cull kept).
pub fn gpu_mask(
    gpu: &GpuCompute,
    passes: &Passes,
    scene: &Scene,
    view: &View,
    light: &ShadowLight,
) -> (Vec<f32>, u32) {
    let run = gpu_mask_at(gpu, passes, scene, view, light, MaskOptions::default());
    (run.values, run.kept)
}

/// [`gpu_mask`] with options.
pub fn gpu_mask_at(
    gpu: &GpuCompute,
    passes: &Passes,
    scene: &Scene,
    view: &View,
    light: &ShadowLight,
    options: MaskOptions<'_>,
) -> MaskRun {
    let stride = options.stride;
    let mask_size = if options.samples.is_some() {
        UVec2::new(2 * WIDTH, 2 * HEIGHT)
    } else if stride == 2 {
        penumbra_df_core::shadow::half_size(UVec2::new(WIDTH, HEIGHT))
    } else {
        UVec2::new(WIDTH, HEIGHT)
    };
    let n = scene.records.len() as u32;
    let record_bytes: Vec<u8> = scene.records.iter().flat_map(|r| r.to_bytes()).collect();
    let objects = gpu.buffer("objects", &record_bytes, BufferUsages::empty());
    let (groups, groups_x) = grid_64(n);
    let cull_view = gpu.buffer(
        "cull_view",
        &words_to_bytes(&cull_view_words(&view.frustum, &view.camera, n, groups_x)),
        BufferUsages::UNIFORM,
    );
    let light_buffer = gpu.buffer(
        "light",
        &words_to_bytes(&light.to_words()),
        BufferUsages::UNIFORM,
    );
    let list = gpu.zeroed("list", n as u64 * 4, BufferUsages::empty());
    let count = gpu.zeroed("count", 4, BufferUsages::empty());
    let bind = gpu.bind(
        &passes.cull,
        &[
            (0, &objects),
            (1, &cull_view),
            (2, &light_buffer),
            (3, &list),
            (4, &count),
        ],
    );
    gpu.dispatch(&passes.cull, &bind, groups);
    let kept = u32::from_le_bytes(gpu.read(&count, 4)[..4].try_into().expect("4 bytes"));

    // Directional lights: the light-space grid of the kept casters.
    let grid = gpu.zeroed("grid", SHADOW_GRID_BYTES as u64, BufferUsages::empty());
    let items = gpu.zeroed(
        "grid_items",
        (n as u64 * SHADOW_GRID_MAX_CELLS as u64 * 4).max(16),
        BufferUsages::empty(),
    );
    let large = gpu.zeroed("grid_large", n as u64 * 4, BufferUsages::empty());
    let cursors = gpu.zeroed("grid_cursors", 4096, BufferUsages::empty());
    let directional = match light.kind {
        ShadowLightKind::Directional(to_light) => Some(to_light),
        ShadowLightKind::Positional(_) => None,
    };
    let use_grid = directional.is_some() && options.use_grid;
    let mut grid_stats = None;
    let grid_view = gpu.buffer(
        "grid_view",
        &words_to_bytes(&grid_view_words(
            &view.camera,
            directional.unwrap_or(Vec3::Y),
            use_grid,
        )),
        BufferUsages::UNIFORM,
    );
    if use_grid {
        let [reset, bounds, count_pass, scan, fill] = &passes.grid;
        let groups = [n.div_ceil(64), 1, 1];
        let all = [
            (0, &objects),
            (1, &list),
            (2, &count),
            (3, &grid_view),
            (4, &grid),
        ];
        gpu.dispatch(reset, &gpu.bind(reset, &[(4, &grid)]), [1, 1, 1]);
        gpu.dispatch(bounds, &gpu.bind(bounds, &all), groups);
        let mut with_large = all.to_vec();
        with_large.push((6, &large));
        gpu.dispatch(count_pass, &gpu.bind(count_pass, &with_large), groups);
        gpu.dispatch(scan, &gpu.bind(scan, &[(4, &grid)]), [1, 1, 1]);
        let mut with_items = all.to_vec();
        with_items.extend([(5, &items), (7, &cursors)]);
        gpu.dispatch(fill, &gpu.bind(fill, &with_items), groups);
        let words = floats_u32(&gpu.read(&grid, 24));
        grid_stats = Some((words[4], words[5]));
    }

    let size = |w, h, d| wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: d,
    };
    let ViewInputs {
        atlas,
        brick_table,
        depth,
        gbuffer,
    } = view_inputs(gpu, scene, view);
    let unwritten: Vec<u8> = match options.samples {
        Some(_) => (0..mask_size.x * mask_size.y)
            .flat_map(|_| UNWRITTEN.to_le_bytes())
            .collect(),
        None => Vec::new(),
    };
    let mask = gpu.texture(
        "mask",
        size(mask_size.x, mask_size.y, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::R32Float,
        4,
        &unwritten,
    );
    let (terrain_records, heights) = terrain_inputs(gpu, &scene.terrain);
    // Bevy's G-buffer layout: the normal word in the fourth channel.
    let trace_view = gpu.buffer(
        "trace_view",
        &words_to_bytes(&trace_view_words(
            view.view_from_clip,
            view.world_from_view,
            &view.camera,
            mask_size,
            stride,
            TRACE_GBUFFER_NORMALS
                | if options.facets.is_some() {
                    TRACE_FACE_NORMALS
                } else {
                    0
                },
            scene.terrain.records.len() as u32,
            UVec4::new(0, 0, WIDTH, HEIGHT),
        )),
        BufferUsages::UNIFORM,
    );
    let (depth, gbuffer) = match options.samples {
        Some(t) => (&t.ms.depth, &t.ms.gbuffer),
        None => (&depth, &gbuffer),
    };
    let view_of = |t: &wgpu::Texture| t.create_view(&Default::default());
    let views = [
        view_of(&atlas),
        view_of(depth),
        view_of(&mask),
        view_of(gbuffer),
        view_of(&brick_table),
    ];
    let class = options.samples.map(|t| view_of(&t.class));
    // The face-normal prepass's target (one texel when there is none).
    let facet_bytes: Vec<u8> = match options.facets {
        Some((f, _)) => f
            .iter()
            .flat_map(|n| [n.x, n.y, n.z, if *n == Vec3::ZERO { 0.0 } else { 1.0 }])
            .flat_map(f32::to_le_bytes)
            .collect(),
        None => vec![0; 16],
    };
    let facet_size = match options.facets {
        Some(_) => size(WIDTH, HEIGHT, 1),
        None => size(1, 1, 1),
    };
    let facet_texture = gpu.texture(
        "facets",
        facet_size,
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Float,
        16,
        &facet_bytes,
    );
    let facet_view = view_of(&facet_texture);
    let facet_depth_bytes: Vec<u8> = match options.facets {
        Some((_, d)) => d.iter().flat_map(|d| d.to_le_bytes()).collect(),
        None => vec![0; 4],
    };
    let facet_depth = gpu.texture(
        "facet_depth",
        facet_size,
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::R32Float,
        4,
        &facet_depth_bytes,
    );
    let facet_depth_view = view_of(&facet_depth);
    let texture = wgpu::BindingResource::TextureView;
    let mut entries = vec![
        (0, objects.as_entire_binding()),
        (1, list.as_entire_binding()),
        (2, count.as_entire_binding()),
        (3, texture(&views[0])),
        (4, texture(&views[1])),
        (5, trace_view.as_entire_binding()),
        (6, light_buffer.as_entire_binding()),
        (7, texture(&views[2])),
        (8, grid.as_entire_binding()),
        (9, items.as_entire_binding()),
        (10, large.as_entire_binding()),
        (11, grid_view.as_entire_binding()),
        (12, texture(&views[3])),
        (13, terrain_records.as_entire_binding()),
        (14, texture(&heights)),
    ];
    match &class {
        Some(class) => entries.extend([(15, texture(class)), (16, texture(&views[4]))]),
        None => entries.extend([
            (15, texture(&views[4])),
            (16, texture(&facet_view)),
            (17, texture(&facet_depth_view)),
        ]),
    }
    let (pipeline, layout) = match options.samples {
        Some(t) => (&t.pipeline, &t.layout),
        None => (&passes.trace, &passes.trace_layout),
    };
    let entries: Vec<_> = entries
        .into_iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
        .collect();
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("shadow_trace"),
        layout,
        entries: &entries,
    });
    let groups = [mask_size.x.div_ceil(8), mask_size.y.div_ceil(8), 1];
    gpu.dispatch(pipeline, &bind, groups);
    let values = floats(&gpu.read_texture_2d(&mask));
    let mut times = Vec::new();
    if options.time {
        for _ in 0..5 {
            gpu.wait();
            let start = std::time::Instant::now();
            gpu.dispatch(pipeline, &bind, groups);
            gpu.wait();
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    MaskRun {
        values,
        kept,
        texture: mask,
        grid: grid_stats,
        times,
    }
}

/// The passes' scene and view inputs on the GPU: the atlas (`R16Float`), the depth
/// buffer (`R32Float`) and the G-buffer (`Rgba32Uint`, the packed normal in `.a`).
pub struct ViewInputs {
    pub atlas: wgpu::Texture,
    /// The brick table (`R32Uint`, `penumbra_df_core::bricks::TABLE_WIDTH` wide).
    pub brick_table: wgpu::Texture,
    pub depth: wgpu::Texture,
    pub gbuffer: wgpu::Texture,
}

/// The scene's atlas as the GPU's `R16Float` 3D texture.
pub fn atlas_texture(gpu: &GpuCompute, scene: &Scene) -> wgpu::Texture {
    let bytes: Vec<u8> = scene
        .atlas_bits
        .iter()
        .flat_map(|b| b.to_le_bytes())
        .collect();
    let s = scene.atlas_size;
    gpu.texture(
        "atlas",
        wgpu::Extent3d {
            width: s.x,
            height: s.y,
            depth_or_array_layers: s.z,
        },
        wgpu::TextureDimension::D3,
        wgpu::TextureFormat::R16Float,
        2,
        &bytes,
    )
}

pub fn view_inputs(gpu: &GpuCompute, scene: &Scene, view: &View) -> ViewInputs {
    let size = |w, h, d| wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: d,
    };
    let atlas = atlas_texture(gpu, scene);
    let brick_table = brick_table_texture(gpu, &scene.atlas);
    let depth_bytes: Vec<u8> = view.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
    let depth = gpu.texture(
        "depth",
        size(WIDTH, HEIGHT, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::R32Float,
        4,
        &depth_bytes,
    );
    let gbuffer_bytes: Vec<u8> = view
        .normals
        .iter()
        .flat_map(|&n| [0u32, 0, 0, n])
        .flat_map(u32::to_le_bytes)
        .collect();
    let gbuffer = gpu.texture(
        "gbuffer",
        size(WIDTH, HEIGHT, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Uint,
        16,
        &gbuffer_bytes,
    );
    ViewInputs {
        atlas,
        brick_table,
        depth,
        gbuffer,
    }
}

/// The model atlas's brick table as the GPU's `R32Uint` texture (one row at least).
pub fn brick_table_texture(gpu: &GpuCompute, atlas: &Atlas) -> wgpu::Texture {
    let width = penumbra_df_core::bricks::TABLE_WIDTH;
    let rows = (atlas.table.len() as u32).div_ceil(width).max(1);
    let mut bytes: Vec<u8> = atlas.table.iter().flat_map(|e| e.to_le_bytes()).collect();
    bytes.resize((width * rows * 4) as usize, 0);
    gpu.texture(
        "brick_table",
        wgpu::Extent3d {
            width,
            height: rows,
            depth_or_array_layers: 1,
        },
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::R32Uint,
        4,
        &bytes,
    )
}

pub fn floats_u32(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

pub fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

pub fn lights(offset: Vec3, eye: Vec3) -> [(&'static str, ShadowLight); 4] {
    let base = ShadowLight {
        kind: ShadowLightKind::Directional(Vec3::new(0.7, 0.6, 0.4).normalize()),
        source: (6.0f32.to_radians() * 0.5).tan(),
        max_distance: 30.0,
        bias: 0.02,
        shaping: 1.0,
        range: 20.0,
        max_steps: 64,
        max_view_distance: f32::INFINITY,
        spot: None,
    };
    [
        ("sun 6°", base),
        (
            // A bias above two of the torus's voxels (4.4 cm): its march starts at two
            // voxels (`march_start`'s fine-field rule), the analytic shapes' at the bias.
            "sphere light r = 0.25 m",
            ShadowLight {
                kind: ShadowLightKind::Positional(Vec3::new(-0.5, 3.5, 1.5) + offset - eye),
                source: 0.25,
                bias: 0.12,
                ..base
            },
        ),
        (
            // Cuts through the view: farther pixels stay lit, and the light cull keeps
            // only casters that can shadow nearer ones.
            "sun 6°, max view distance 4.3 m",
            ShadowLight {
                max_view_distance: 4.3,
                spot: None,
                ..base
            },
        ),
        (
            // Pixels beyond the range or outside the cone are not traced (lit); whole
            // tiles outside gather no caster.
            "spot 35°, range 4.5 m",
            ShadowLight {
                kind: ShadowLightKind::Positional(Vec3::new(-0.5, 3.5, 1.5) + offset - eye),
                source: 0.1,
                range: 4.5,
                spot: Some((
                    (Vec3::new(0.1, 0.3, -0.6) - Vec3::new(-0.5, 3.5, 1.5)).normalize(),
                    35f32.to_radians().cos(),
                )),
                ..base
            },
        ),
    ]
}

/// `(mean |gpu − cpu|, fraction over 0.05, max)`.
pub fn compare(gpu: &[f32], cpu: &[f32]) -> (f32, f32, f32) {
    let diffs: Vec<f32> = gpu.iter().zip(cpu).map(|(a, b)| (a - b).abs()).collect();
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    let over = diffs.iter().filter(|&&d| d > 0.05).count() as f32 / diffs.len() as f32;
    (mean, over, diffs.iter().copied().fold(0.0, f32::max))
}

/// Hills over 12 × 12 m around the scene's origin, 1.5 m high at most, dipping below
/// the plane (49 × 49 samples), or none.
pub fn hills(offset: Vec3) -> HeightfieldTexture {
    let size = UVec2::new(49, 49);
    let heights = (0..size.y)
        .flat_map(|j| (0..size.x).map(move |i| (i as f32 / 4.0 - 6.0, j as f32 / 4.0 - 6.0)))
        .map(|(x, z)| offset.y - 0.4 + 1.2 * (0.7 * x).sin().powi(2) * (0.5 * z).cos())
        .collect();
    let h = Heightfield::new(
        size,
        Vec2::new(offset.x - 6.0, offset.z - 6.0),
        Vec2::splat(12.0),
        heights,
    )
    .expect("valid");
    HeightfieldTexture::pack(&[&h], 4096).0
}

/// The terrains' records buffer (one zeroed record when there is none) and texture
/// view, as the passes bind them.
pub fn terrain_inputs(
    gpu: &GpuCompute,
    terrain: &HeightfieldTexture,
) -> (wgpu::Buffer, wgpu::TextureView) {
    let mut records = terrain.records.clone();
    records.resize(records.len().max(1), Default::default());
    let mut bytes = bevy::render::render_resource::encase::StorageBuffer::new(Vec::new());
    bytes.write(&records).expect("encodes");
    let buffer = gpu.buffer("terrains", bytes.as_ref(), BufferUsages::empty());
    let texels: Vec<u8> = terrain
        .texels
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let heights = gpu
        .texture(
            "heights",
            wgpu::Extent3d {
                width: terrain.width.max(1),
                height: terrain.rows.max(1),
                depth_or_array_layers: 1,
            },
            wgpu::TextureDimension::D2,
            wgpu::TextureFormat::R32Float,
            4,
            &texels,
        )
        .create_view(&Default::default());
    (buffer, heights)
}
