//! The fuzz targets: each takes arbitrary bytes, turns them into one of Penumbra's inputs
//! and runs what a user's file or mesh reaches. A target returns normally for any
//! input; a panic, a hang or an allocation over the limit is a defect.

use base64::Engine;
use glam::{Vec2, Vec3, Vec4};
use penumbra_cinematic_core::hair::strands::{check_strands, parse_hair, strands_from_ribbons};
use penumbra_cinematic_core::tessellation::{SourceMesh, TessellationInput};
use penumbra_sdf::gltf_input::{GltfSelection, load_gltf_with_sides};
use penumbra_sdf::{BakeSettings, TriMesh, bake, format, obj::parse_obj, openness};

/// One fuzz target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// `.psdf` files (`penumbra_sdf::format::from_bytes`); the CRC is recomputed so the
    /// fuzzer reaches what lies behind it.
    Psdf,
    /// Wavefront OBJ text, then the mesh checks, the openness measure and, for small
    /// meshes, a bake (`penumbra-bake`'s path).
    Obj,
    /// glTF and GLB bytes (`load_gltf_with_sides`, the scene selection), then as OBJ.
    Gltf,
    /// `.hair` text (`parse_hair`, `check_strands`).
    Hair,
    /// Ribbon meshes (`strands_from_ribbons`), as `HairStrands::from_ribbon_mesh` reads them.
    Ribbons,
    /// Meshes handed to tessellation (`TessellationInput::new`).
    Tessellation,
}

impl Target {
    /// Every target, in the order `cargo xtask fuzz` runs them.
    pub const ALL: [Target; 6] = [
        Target::Psdf,
        Target::Obj,
        Target::Gltf,
        Target::Hair,
        Target::Ribbons,
        Target::Tessellation,
    ];

    /// The target's name: its corpus folder and its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::Psdf => "psdf",
            Target::Obj => "obj",
            Target::Gltf => "gltf",
            Target::Hair => "hair",
            Target::Ribbons => "ribbons",
            Target::Tessellation => "tessellation",
        }
    }

    /// Runs the target on `data`.
    pub fn run(self, data: &[u8]) {
        match self {
            Target::Psdf => psdf(data),
            Target::Obj => obj(data),
            Target::Gltf => gltf(data),
            Target::Hair => hair(data),
            Target::Ribbons => ribbons(data),
            Target::Tessellation => tessellation(data),
        }
    }

    /// Tokens the mutator splices in (the format's keywords and awkward numbers).
    pub fn dictionary(self) -> &'static [&'static [u8]] {
        const NUMBERS: &[&[u8]] = &[
            b"0",
            b"-1",
            b"1e39",
            b"-1e39",
            b"nan",
            b"inf",
            b"-inf",
            b"4294967295",
            b"4294967296",
            b"2147483648",
            b"1e-45",
            b"0.5",
            b"-0",
        ];
        match self {
            Target::Psdf => &[
                b"PSDF",
                b"\x01\0\0\0",
                b"\x02\0\0\0",
                b"\xff\xff\xff\x7f",
                b"\0\0\x80\x7f",
                b"\0\0\xc0\x7f",
            ],
            Target::Obj => &[
                b"v ",
                b"vt ",
                b"vn ",
                b"f ",
                b"o ",
                b"g ",
                b"s 1",
                b"usemtl m",
                b"mtllib a.mtl",
                b"/",
                b"//",
                b"\n",
                b"1/1/1 ",
                b"-1 ",
                b"-2 ",
                b"0 ",
                b"l 1 2",
                b"p 1",
                b"nan",
                b"1e39",
                b"4294967296",
            ],
            Target::Gltf => &[
                b"\"accessors\"",
                b"\"bufferViews\"",
                b"\"buffers\"",
                b"\"meshes\"",
                b"\"nodes\"",
                b"\"scenes\"",
                b"\"scene\"",
                b"\"primitives\"",
                b"\"attributes\"",
                b"\"POSITION\"",
                b"\"indices\"",
                b"\"mode\"",
                b"\"count\"",
                b"\"componentType\"",
                b"\"type\"",
                b"\"VEC3\"",
                b"\"SCALAR\"",
                b"\"byteOffset\"",
                b"\"byteLength\"",
                b"\"byteStride\"",
                b"\"bufferView\"",
                b"\"sparse\"",
                b"\"values\"",
                b"\"normalized\"",
                b"\"uri\"",
                b"\"data:application/octet-stream;base64,\"",
                b"\"matrix\"",
                b"\"scale\"",
                b"\"rotation\"",
                b"\"translation\"",
                b"\"children\"",
                b"\"mesh\"",
                b"\"skin\"",
                b"\"materials\"",
                b"\"material\"",
                b"\"doubleSided\"",
                b"\"alphaMode\"",
                b"\"BLEND\"",
                b"5126",
                b"5125",
                b"5123",
                b"5121",
                b"5120",
                b"5122",
                b"4294967295",
                b"2000000000",
                b"-1",
                b"1e39",
                b"[",
                b"]",
                b"{",
                b"}",
                b",",
                b":",
                b"null",
                b"glTF",
                b"JSON",
                b"BIN\0",
            ],
            Target::Hair => &[
                b"penumbra-hair 1\n",
                b"strand ",
                b"\n",
                b"# ",
                b" 0.01 0 ",
                b"0 0 0 ",
                b"1 2 3",
            ],
            Target::Ribbons | Target::Tessellation => NUMBERS,
        }
    }

    /// Small valid inputs the search starts from (with the committed corpus).
    pub fn seeds(self) -> Vec<Vec<u8>> {
        match self {
            Target::Psdf => {
                let volume = penumbra_sdf::SdfVolume::from_distances(
                    glam::UVec3::splat(3),
                    glam::DVec3::ZERO,
                    0.5,
                    [0.25; 27],
                );
                vec![format::to_bytes(&volume)]
            }
            Target::Obj => vec![CUBE_OBJ.as_bytes().to_vec()],
            Target::Gltf => vec![triangle_gltf().into_bytes(), triangle_glb()],
            Target::Hair => vec![
                b"penumbra-hair 1\nstrand 0.01 0 0 0 0 0 1 0 0 2 0\nstrand 0.02 3 1 0 0 1 1 0\n"
                    .to_vec(),
            ],
            Target::Ribbons => vec![encode_mesh(
                &[
                    [0.0, 0.0, 0.0],
                    [0.1, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.1, 1.0, 0.0],
                    [0.0, 2.0, 0.0],
                    [0.1, 2.0, 0.0],
                ],
                &[
                    [0.2, 0.0],
                    [0.2, 0.0],
                    [0.2, 0.5],
                    [0.2, 0.5],
                    [0.2, 1.0],
                    [0.2, 1.0],
                ],
                &[0, 1, 2, 2, 1, 3, 2, 3, 4, 4, 3, 5],
                FLAG_UVS,
            )],
            Target::Tessellation => vec![encode_mesh(
                &[
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.0, 0.0, 1.0],
                ],
                &[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
                &[0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3],
                FLAG_UVS | FLAG_NORMALS | FLAG_TANGENTS,
            )],
        }
    }
}

const CUBE_OBJ: &str = "o cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
vt 0 0\nvn 0 0 1\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

/// A triangle as glTF JSON with an embedded (`data:`) buffer.
fn triangle_gltf() -> String {
    let bytes = triangle_buffer();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0,"scale":[1,2,1]}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},{{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}],"bufferViews":[{{"buffer":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":6}}],"buffers":[{{"byteLength":42,"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// The same triangle as a GLB (binary chunk).
fn triangle_glb() -> Vec<u8> {
    let json = triangle_gltf();
    let json = json.replace(
        r#","uri":"data:application/octet-stream;base64,"#,
        r#","x":""#,
    );
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = triangle_buffer();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

fn triangle_buffer() -> Vec<u8> {
    let mut bytes = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2] {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    bytes
}

/// `.psdf`: the stored CRC is replaced by the right one before parsing.
fn psdf(data: &[u8]) {
    let mut bytes = data.to_vec();
    let header = match bytes
        .get(4..8)
        .map(|v| u32::from_le_bytes(v.try_into().expect("4 bytes")))
    {
        Some(1) => 40,
        Some(2) => 56,
        _ => 0,
    };
    if header > 0 && bytes.len() >= header {
        let crc = format::crc32(format::crc32(0, &bytes[..header - 4]), &bytes[header..]);
        bytes[header - 4..header].copy_from_slice(&crc.to_le_bytes());
    }
    if let Ok(volume) = format::from_bytes(&bytes) {
        std::hint::black_box(volume.measured_margin());
        std::hint::black_box(volume.bounds());
        std::hint::black_box(format::to_npy(&volume).len());
    }
}

/// What every mesh read from a file goes through.
fn mesh(mesh: &TriMesh) {
    let Ok((triangles, _)) = mesh.validate() else {
        return;
    };
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    std::hint::black_box(openness::open_index(&mesh.positions, &indices));
    if triangles.len() <= 16 {
        std::hint::black_box(bake(mesh, &BakeSettings::longest_axis(6), None).ok());
    }
}

fn obj(data: &[u8]) {
    if let Ok(m) = parse_obj(&String::from_utf8_lossy(data)) {
        mesh(&m);
    }
}

fn gltf(data: &[u8]) {
    if let Ok((m, _, _)) = load_gltf_with_sides(data, None, &GltfSelection::Scene) {
        mesh(&m);
    }
}

fn hair(data: &[u8]) {
    if let Ok(strands) = parse_hair(&String::from_utf8_lossy(data)) {
        std::hint::black_box(check_strands(strands));
    }
}

fn ribbons(data: &[u8]) {
    let m = decode_mesh(data);
    let strands = strands_from_ribbons(&m.positions, &m.uvs, &m.indices, u32::from(m.slots));
    std::hint::black_box(check_strands(strands));
}

fn tessellation(data: &[u8]) {
    let m = decode_mesh(data);
    let source = SourceMesh {
        positions: &m.positions,
        normals: (m.flags & FLAG_NORMALS != 0).then_some(&m.normals[..]),
        uvs: (m.flags & FLAG_UVS != 0).then_some(&m.uvs[..]),
        tangents: (m.flags & FLAG_TANGENTS != 0).then_some(&m.tangents[..]),
        indices: &m.indices,
    };
    if let Ok(input) = TessellationInput::new(source) {
        std::hint::black_box(input.patch_words());
    }
}

const FLAG_NORMALS: u8 = 1;
const FLAG_UVS: u8 = 2;
const FLAG_TANGENTS: u8 = 4;
/// Vertices a decoded mesh holds at most (more would only slow the search).
const MAX_VERTICES: usize = 512;

/// A mesh decoded from fuzz bytes.
struct DecodedMesh {
    flags: u8,
    slots: u8,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    tangents: Vec<Vec4>,
    indices: Vec<u32>,
}

/// Layout: `flags: u8` (1 normals, 2 uvs, 4 tangents; bit 3 one attribute a vertex
/// short), `slots: u8`, `vertices: u16`, then per vertex its floats (position, then
/// the attributes the flags name), then the indices as `u16`s (so they mostly land in
/// range; one above the vertex count is out of range). Floats are raw bits: NaN and
/// infinities are reached.
fn decode_mesh(data: &[u8]) -> DecodedMesh {
    let flags = data.first().copied().unwrap_or(0);
    let slots = data.get(1).copied().unwrap_or(1);
    let n = data
        .get(2..4)
        .map_or(0, |b| usize::from(u16::from_le_bytes([b[0], b[1]])))
        .min(MAX_VERTICES);
    let mut rest = data.get(4..).unwrap_or(&[]);
    let mut float = || {
        let (head, tail) = rest.split_at(rest.len().min(4));
        rest = tail;
        let mut b = [0u8; 4];
        b[..head.len()].copy_from_slice(head);
        f32::from_le_bytes(b)
    };
    let mut m = DecodedMesh {
        flags,
        slots,
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        tangents: Vec::new(),
        indices: Vec::new(),
    };
    for i in 0..n {
        m.positions.push(Vec3::new(float(), float(), float()));
        let short = flags & 8 != 0 && i + 1 == n;
        if flags & FLAG_NORMALS != 0 && !short {
            m.normals.push(Vec3::new(float(), float(), float()));
        }
        if flags & FLAG_UVS != 0 || flags & 7 == 0 {
            m.uvs.push(Vec2::new(float(), float()));
        }
        if flags & FLAG_TANGENTS != 0 && !short {
            m.tangents
                .push(Vec4::new(float(), float(), float(), float()));
        }
    }
    m.indices = rest
        .chunks_exact(2)
        .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
        .collect();
    m
}

/// Encodes a mesh as [`decode_mesh`] reads it (seeds).
fn encode_mesh(positions: &[[f32; 3]], uvs: &[[f32; 2]], indices: &[u16], flags: u8) -> Vec<u8> {
    let mut out = vec![flags, 4];
    out.extend_from_slice(&(positions.len() as u16).to_le_bytes());
    for (p, uv) in positions.iter().zip(uvs) {
        let mut floats: Vec<f32> = p.to_vec();
        if flags & FLAG_NORMALS != 0 {
            floats.extend([0.0, 0.0, 1.0]);
        }
        if flags & FLAG_UVS != 0 {
            floats.extend(uv);
        }
        if flags & FLAG_TANGENTS != 0 {
            floats.extend([1.0, 0.0, 0.0, 1.0]);
        }
        for f in floats {
            out.extend_from_slice(&f.to_le_bytes());
        }
    }
    for i in indices {
        out.extend_from_slice(&i.to_le_bytes());
    }
    out
}
