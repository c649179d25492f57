//! The hair strips' Bevy material: its uniform, the atlas binding, and the pipeline
//! specialisation that picks the coverage method (per-sample mask under 4× MSAA, the
//! comparisons, the per-pixel fallback without MSAA) and the strips' vertex layout.

use bevy::asset::uuid_handle;
use bevy::mesh::{MeshVertexAttribute, MeshVertexBufferLayoutRef, VertexFormat};
use bevy::pbr::{MaterialPipeline, MaterialPipelineKey};
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, RenderPipelineDescriptor, ShaderType, SpecializedMeshPipelineError,
};
use bevy::render::storage::ShaderBuffer;
use bevy::shader::{ShaderDefVal, ShaderRef};

use super::HairCoverage;

/// The strand's direction at a vertex (hair space).
pub const ATTRIBUTE_HAIR_TANGENT: MeshVertexAttribute = MeshVertexAttribute::new(
    "PenumbraHairTangent",
    0x7065_6e75_6d62_0001,
    VertexFormat::Float32x3,
);
/// Side (−1 or +1), u along the strand (0 root, 1 tip), width (metres), atlas slot.
pub const ATTRIBUTE_HAIR_STRIP: MeshVertexAttribute = MeshVertexAttribute::new(
    "PenumbraHairStrip",
    0x7065_6e75_6d62_0002,
    VertexFormat::Float32x4,
);

pub(crate) const DRAW_SHADER: Handle<Shader> = uuid_handle!("6a1f7c52-3d0e-4f8b-9c41-2b7e5d90a3c6");
pub(crate) const PREPASS_SHADER: Handle<Shader> =
    uuid_handle!("0d9e4b27-81c3-4a5f-b6e2-7f3a1c58d904");

/// `penumbra::hair::common`'s `HairParams`.
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct HairParams {
    /// Linear RGB at the root (alpha unused).
    pub root_color: Vec4,
    /// Linear RGB at the tip.
    pub tip_color: Vec4,
    /// Primary strength, exponent; secondary strength, exponent.
    pub specular: Vec4,
    /// The primary lobe's tangent shift.
    pub primary_shift: f32,
    /// The secondary lobe's tangent shift.
    pub secondary_shift: f32,
    /// Multiplies every strand's width.
    pub width_scale: f32,
    /// Slots across the atlas.
    pub atlas_slots: u32,
    /// `1`: an atlas is bound; `2`: coverage debug view (white).
    pub flags: u32,
}

/// Lights one hair entity takes from the distance fields (`penumbra::hair::shadows`'s
/// `MAX_HAIR_SHADOW_LIGHTS`), of those that reach it (a point or spot light's range);
/// with more, the lights keep their shadow maps.
pub const MAX_HAIR_SHADOW_LIGHTS: usize = 4;

/// Bytes of `penumbra::hair::shadows`'s `HairShadows` before its points: the counts and
/// four lights.
pub const HAIR_SHADOWS_HEADER_BYTES: usize = 16 + 32 * MAX_HAIR_SHADOW_LIGHTS;

/// Flag: an atlas is bound.
pub const HAIR_FLAG_ATLAS: u32 = 1;
/// Flag: draw coverage only (white).
pub const HAIR_FLAG_DEBUG_COVERAGE: u32 = 2;

/// The material a [`super::Hair`] entity's strips are drawn with (made and kept up to
/// date by the plugin from the component; not meant to be built by hand).
#[derive(Asset, TypePath, AsBindGroup, Clone, Debug)]
#[bind_group_data(HairMaterialKey)]
pub struct HairMaterial {
    /// The shading parameters.
    #[uniform(0)]
    pub params: HairParams,
    /// The atlas of hairs, if any.
    #[texture(1)]
    #[sampler(2)]
    pub atlas: Option<Handle<Image>>,
    /// The strands' distance-field visibility (`penumbra::hair::shadows`'s
    /// `HairShadows`): the entity's own buffer while distance-field-shadowed lights
    /// exist, otherwise the plugin's shared placeholder with no light.
    #[storage(3, read_only, visibility(vertex, fragment))]
    pub shadows: Handle<ShaderBuffer>,
    /// How coverage is computed.
    pub coverage: HairCoverage,
}

/// The pipeline key of a [`HairMaterial`].
#[repr(C)]
#[derive(Eq, PartialEq, Hash, Copy, Clone)]
pub struct HairMaterialKey {
    coverage: HairCoverage,
}

impl From<&HairMaterial> for HairMaterialKey {
    fn from(material: &HairMaterial) -> Self {
        Self {
            coverage: material.coverage,
        }
    }
}

impl Material for HairMaterial {
    fn vertex_shader() -> ShaderRef {
        DRAW_SHADER.into()
    }

    fn fragment_shader() -> ShaderRef {
        DRAW_SHADER.into()
    }

    fn prepass_vertex_shader() -> ShaderRef {
        PREPASS_SHADER.into()
    }

    fn prepass_fragment_shader() -> ShaderRef {
        PREPASS_SHADER.into()
    }

    /// Masked: the prepass and shadow passes run the fragment shader (its coverage).
    fn alpha_mode(&self) -> AlphaMode {
        AlphaMode::Mask(0.5)
    }

    fn specialize(
        _pipeline: &MaterialPipeline,
        descriptor: &mut RenderPipelineDescriptor,
        layout: &MeshVertexBufferLayoutRef,
        key: MaterialPipelineKey<Self>,
    ) -> Result<(), SpecializedMeshPipelineError> {
        let mut attributes = vec![
            Mesh::ATTRIBUTE_POSITION.at_shader_location(0),
            ATTRIBUTE_HAIR_TANGENT.at_shader_location(1),
            ATTRIBUTE_HAIR_STRIP.at_shader_location(2),
        ];
        if layout.0.contains(Mesh::ATTRIBUTE_JOINT_INDEX) {
            attributes.push(Mesh::ATTRIBUTE_JOINT_INDEX.at_shader_location(3));
            attributes.push(Mesh::ATTRIBUTE_JOINT_WEIGHT.at_shader_location(4));
        }
        descriptor.vertex.buffers = vec![layout.0.get_layout(&attributes)?];
        // Strips face the camera; either winding.
        descriptor.primitive.cull_mode = None;

        let prepass = descriptor
            .vertex
            .shader_defs
            .contains(&ShaderDefVal::from("PREPASS_PIPELINE"));
        let multisampled = key.mesh_key.msaa_samples() > 1;
        let coverage = key.bind_group_data.coverage;
        let mut defs: Vec<ShaderDefVal> = Vec::new();
        let mut entry = None;
        if multisampled {
            // The sample pattern tested (`hair/samples.wgsl`; 4× without a definition).
            match key.mesh_key.msaa_samples() {
                2 => defs.push("HAIR_SAMPLES_2".into()),
                8 => defs.push("HAIR_SAMPLES_8".into()),
                _ => {}
            }
            match coverage {
                HairCoverage::PerPixel => {}
                HairCoverage::AlphaToCoverage if !prepass => {
                    entry = Some("fragment_alpha_to_coverage");
                    descriptor.multisample.alpha_to_coverage_enabled = true;
                }
                HairCoverage::SampleShading if !prepass => {
                    entry = Some("fragment_sample_shading");
                    defs.push("HAIR_SAMPLE_SHADING".into());
                }
                // The prepass of the comparisons writes the per-sample mask's depth.
                _ => defs.push("HAIR_PER_SAMPLE".into()),
            }
        }
        descriptor.vertex.shader_defs.extend(defs.iter().cloned());
        if let Some(fragment) = descriptor.fragment.as_mut() {
            fragment.shader_defs.extend(defs);
            // `hair/draw.wgsl` has several fragment entry points.
            fragment.entry_point = Some(entry.unwrap_or("fragment").into());
        }
        Ok(())
    }
}
