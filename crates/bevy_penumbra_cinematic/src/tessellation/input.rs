//! A tessellated entity's inputs from Bevy's assets: the mesh's preprocessing, the
//! displacement image's heights, the input vertices' GPU layout and the output mesh.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use penumbra_cinematic_core::tessellation::shapes::ShapeMesh;
use penumbra_cinematic_core::tessellation::{DisplacementMap, SourceMesh, TessellationInput};

fn f32x3(mesh: &Mesh, attribute: bevy::mesh::MeshVertexAttribute) -> Option<Vec<Vec3>> {
    match mesh.attribute(attribute)? {
        VertexAttributeValues::Float32x3(v) => {
            Some(v.iter().map(|&a| Vec3::from_array(a)).collect())
        }
        _ => None,
    }
}

/// Preprocesses `mesh` (an error message when it cannot be tessellated).
pub(super) fn preprocess(mesh: &Mesh) -> Result<TessellationInput, String> {
    // Once this succeeds every attribute, the indices and the morph targets are readable.
    if mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION).is_err() {
        return Err("its mesh's data is in the render world only (keep \
                    RenderAssetUsages::MAIN_WORLD in its asset usage, or tessellate \
                    the source mesh, not another entity's tessellated output)"
            .into());
    }
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(format!(
            "its mesh is a {:?}, not a triangle list",
            mesh.primitive_topology()
        ));
    }
    if mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX).is_some() || mesh.morph_targets().is_some() {
        return Err("skinned and morphed meshes are not supported".into());
    }
    let positions =
        f32x3(mesh, Mesh::ATTRIBUTE_POSITION).ok_or("its mesh has no Float32x3 positions")?;
    let normals = f32x3(mesh, Mesh::ATTRIBUTE_NORMAL);
    let uvs = match mesh.attribute(Mesh::ATTRIBUTE_UV_0) {
        Some(VertexAttributeValues::Float32x2(v)) => {
            Some(v.iter().map(|&a| Vec2::from_array(a)).collect::<Vec<_>>())
        }
        _ => None,
    };
    let tangents = match mesh.attribute(Mesh::ATTRIBUTE_TANGENT) {
        Some(VertexAttributeValues::Float32x4(v)) => {
            Some(v.iter().map(|&a| Vec4::from_array(a)).collect::<Vec<_>>())
        }
        _ => None,
    };
    let indices: Vec<u32> = match mesh.indices() {
        Some(i) => i.iter().map(|i| i as u32).collect(),
        None => (0..positions.len() as u32).collect(),
    };
    TessellationInput::new(SourceMesh {
        positions: &positions,
        normals: normals.as_deref(),
        uvs: uvs.as_deref(),
        tangents: tangents.as_deref(),
        indices: &indices,
    })
    .map_err(|e| format!("its mesh cannot be tessellated: {e}"))
}

/// The heights of an image's red channel, or why not.
pub(super) fn heights(image: &Image) -> Result<DisplacementMap, String> {
    let size = image.size();
    let data = image
        .data
        .as_ref()
        .ok_or("its displacement image has no CPU data")?;
    let texels = (size.x * size.y) as usize;
    let read = |stride: usize, f: &dyn Fn(&[u8]) -> f32| -> Vec<f32> {
        data.chunks_exact(stride).take(texels).map(f).collect()
    };
    let r16 = |b: &[u8]| u16::from_le_bytes([b[0], b[1]]);
    let values = match image.texture_descriptor.format {
        TextureFormat::R8Unorm | TextureFormat::Rgba8Unorm | TextureFormat::Rgba8UnormSrgb => {
            let stride = if image.texture_descriptor.format == TextureFormat::R8Unorm {
                1
            } else {
                4
            };
            read(stride, &|b| f32::from(b[0]) / 255.0)
        }
        // 16-bit grey PNGs load as `R16Uint` (`Rg16Uint` with alpha): 0 to 65535.
        TextureFormat::R16Unorm | TextureFormat::R16Uint => {
            read(2, &|b| f32::from(r16(b)) / 65535.0)
        }
        TextureFormat::Rg16Uint => read(4, &|b| f32::from(r16(b)) / 65535.0),
        TextureFormat::Rgba16Unorm | TextureFormat::Rgba16Uint => {
            read(8, &|b| f32::from(r16(b)) / 65535.0)
        }
        TextureFormat::R16Float => read(2, &|b| half::f16::from_bits(r16(b)).to_f32()),
        TextureFormat::Rgba16Float => read(8, &|b| half::f16::from_bits(r16(b)).to_f32()),
        TextureFormat::R32Float => read(4, &|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        TextureFormat::Rgba32Float => read(16, &|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        other => {
            return Err(format!(
                "its displacement image's format {other:?} is not supported (8/16-bit unorm, \
                 16-bit uint as 16-bit PNGs load, or 16/32-bit float)"
            ));
        }
    };
    DisplacementMap::new(size.x, size.y, values)
        .ok_or_else(|| "its displacement image is empty, mis-sized or not finite".into())
}

/// A placeholder mesh of the pool's size, with the attributes the passes write; its GPU
/// buffers are overwritten by the tessellation (never re-uploaded: it is not changed).
pub(super) fn output_mesh(vertices: u32, indices: u32, tangents: bool) -> Mesh {
    let n = vertices as usize;
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::RENDER_WORLD,
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; n])
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n])
    .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, vec![[0.0f32; 2]; n])
    .with_inserted_indices(Indices::U32(vec![0; indices as usize]));
    if tangents {
        mesh.insert_attribute(Mesh::ATTRIBUTE_TANGENT, vec![[1.0f32, 0.0, 0.0, 1.0]; n]);
    }
    mesh
}

/// The input vertices as a WGSL runtime-sized array of `TessVertex`.
pub(super) fn encase_vec(
    items: &Vec<penumbra_cinematic_core::tessellation::TessVertex>,
) -> Vec<u8> {
    let mut buffer = bevy::render::render_resource::encase::StorageBuffer::new(Vec::new());
    buffer.write(items).expect("encodes");
    buffer.into_inner()
}

/// A [`ShapeMesh`] (e.g. `penumbra_cinematic_core::tessellation::shapes::rock`, the
/// examples' and tests' rock) as a Bevy mesh: positions, normals, UV 0, indices.
pub fn shape_mesh(shape: &ShapeMesh) -> Mesh {
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        shape
            .positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_NORMAL,
        shape
            .normals
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_UV_0,
        shape.uvs.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(shape.indices.clone()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::render::render_resource::{Extent3d, TextureDimension};

    /// A mesh as the main world keeps it after extraction when its asset usage lacks
    /// `MAIN_WORLD`: every CPU read of it is an error (or a panic, through the plain
    /// accessors).
    fn extracted(mut mesh: Mesh) -> Mesh {
        mesh.take_gpu_data().expect("a fresh mesh has its data");
        mesh
    }

    /// Found by the soak: a copy of a tessellated entity carries its render-world-only
    /// output mesh; preprocessing it panicked in Bevy's `Mesh::attribute`.
    #[test]
    fn a_mesh_in_the_render_world_only_is_refused_with_the_reason() {
        let mesh = extracted(Plane3d::default().mesh().subdivisions(2).build());
        let Err(error) = preprocess(&mesh) else {
            panic!("a render-world-only mesh was preprocessed");
        };
        assert!(error.contains("render world only"), "{error}");
    }

    /// Displacement images of every format, size class and data length
    /// (`penumbra_test::awkward_images`): finite heights, the first level the image's
    /// size, or refused with a reason; never a panic.
    #[test]
    fn displacement_images_of_every_format_and_size_are_read_or_refused() {
        penumbra_test::awkward_images::check_image_reader(
            "displacement images",
            33,
            heights,
            |map| {
                (
                    Some(UVec2::new(map.levels[0][0], map.levels[0][1])),
                    map.texels.clone(),
                )
            },
        );
    }

    /// A 16-bit grey PNG displacement map (Bevy's `R16Uint`; `Rg16Uint` with alpha) reads
    /// as its unorm twin does (it was refused, #47).
    #[test]
    fn sixteen_bit_png_displacement_maps_read() {
        let raw = [0u16, 32768, 65535, 16384];
        let image = |format: TextureFormat, channels: usize| {
            let data = raw
                .iter()
                .flat_map(|&x| {
                    let mut texel = vec![0u8; 2 * channels];
                    texel[..2].copy_from_slice(&x.to_le_bytes());
                    texel
                })
                .collect();
            Image::new(
                Extent3d {
                    width: 2,
                    height: 2,
                    depth_or_array_layers: 1,
                },
                TextureDimension::D2,
                data,
                format,
                RenderAssetUsages::all(),
            )
        };
        let want = heights(&image(TextureFormat::R16Unorm, 1)).expect("R16Unorm");
        for (format, channels) in [(TextureFormat::R16Uint, 1), (TextureFormat::Rg16Uint, 2)] {
            let got =
                heights(&image(format, channels)).unwrap_or_else(|e| panic!("{format:?}: {e}"));
            assert_eq!(got, want, "{format:?}");
        }
    }
}
