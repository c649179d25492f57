//! The `.psdf` file format, and `.npy` export.
//!
//! # `.psdf`, version 2 (all integers and floats little-endian)
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `PSDF` |
//! | 4 | 4 | version: u32 = 2 |
//! | 8 | 12 | dims: 3 × u32 (each ≥ 2) |
//! | 20 | 24 | origin: 3 × f64 (position of sample (0, 0, 0), mesh units) |
//! | 44 | 4 | voxel size: f32 (> 0, mesh units) |
//! | 48 | 4 | margin: f32 (≥ 0, voxels: the surface lies at least this far inside the box) |
//! | 52 | 4 | CRC-32 (IEEE) of bytes 0..52 followed by the samples |
//! | 56 | 2·n | n = dims.x·dims.y·dims.z signed distances **in voxels**, IEEE binary16, x fastest |
//!
//! Nothing follows the samples. Version 1 (origin as 3 × f32 at 20, voxel size at 32,
//! CRC at 36, samples in mesh units from 40) is still read, its samples converted to
//! voxels and its margin measured from them ([`SdfVolume::measured_margin`]). The reader rejects other magics and versions, truncated or oversized files,
//! bad dims or voxel sizes, checksum mismatches and NaN or infinite samples with a clear
//! [`FormatError`] (never a panic).

use crate::grid::MAX_SAMPLES;
use crate::volume::SdfVolume;
use glam::{DVec3, UVec3};
use half::f16;

/// File magic.
pub const MAGIC: [u8; 4] = *b"PSDF";
/// The version this code writes (it also reads version 1).
pub const VERSION: u32 = 2;
const HEADER: usize = 56;
const HEADER_V1: usize = 40;

/// Why a `.psdf` file was rejected.
#[derive(Clone, Debug, PartialEq)]
pub enum FormatError {
    /// Not a `.psdf` file.
    BadMagic,
    /// Written by another version of the format.
    UnsupportedVersion(u32),
    /// Shorter than its header says.
    Truncated {
        /// Bytes the header implies.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// Longer than its header says.
    TrailingBytes(usize),
    /// Dims, origin or voxel size out of range.
    BadHeader(String),
    /// The checksum does not match: the file is corrupt.
    ChecksumMismatch {
        /// Stored.
        stored: u32,
        /// Computed.
        computed: u32,
    },
    /// A sample is NaN or infinite (GPU interpolation would spread it).
    NonFiniteSample {
        /// Its index (x fastest).
        index: usize,
    },
}

impl std::fmt::Display for FormatError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FormatError::BadMagic => write!(f, "not a Penumbra SDF file (bad magic)"),
            FormatError::UnsupportedVersion(v) => {
                write!(
                    f,
                    "SDF file version {v} is not supported (this build reads versions 1 and {VERSION})"
                )
            }
            FormatError::Truncated { expected, got } => {
                write!(f, "SDF file truncated: {got} bytes, expected {expected}")
            }
            FormatError::TrailingBytes(n) => {
                write!(f, "SDF file has {n} unexpected trailing bytes")
            }
            FormatError::BadHeader(why) => write!(f, "SDF file header invalid: {why}"),
            FormatError::ChecksumMismatch { stored, computed } => write!(
                f,
                "SDF file corrupt: checksum {computed:#010x} does not match stored {stored:#010x}"
            ),
            FormatError::NonFiniteSample { index } => {
                write!(f, "SDF file holds a NaN or infinite sample (index {index})")
            }
        }
    }
}

impl std::error::Error for FormatError {}

/// CRC-32 (IEEE 802.3, reflected, as zlib's `crc32`), continuing from `crc`.
pub fn crc32(mut crc: u32, bytes: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        std::array::from_fn(|n| {
            (0..8).fold(n as u32, |c, _| {
                if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                }
            })
        })
    });
    crc = !crc;
    for &b in bytes {
        crc = table[((crc ^ b as u32) & 0xff) as usize] ^ (crc >> 8);
    }
    !crc
}

/// Serializes a volume as `.psdf` bytes (version 2).
pub fn to_bytes(v: &SdfVolume) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + 2 * v.data.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    for d in v.dims.to_array() {
        out.extend_from_slice(&d.to_le_bytes());
    }
    for o in v.origin.to_array() {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&v.voxel_size.to_le_bytes());
    out.extend_from_slice(&v.margin.to_le_bytes());
    out.extend_from_slice(&[0; 4]); // checksum, filled below
    for s in &v.data {
        out.extend_from_slice(&s.to_le_bytes());
    }
    let crc = crc32(crc32(0, &out[..HEADER - 4]), &out[HEADER..]);
    out[HEADER - 4..HEADER].copy_from_slice(&crc.to_le_bytes());
    out
}

/// Parses `.psdf` bytes (version 2, or 1).
pub fn from_bytes(bytes: &[u8]) -> Result<SdfVolume, FormatError> {
    if bytes.len() < 8 {
        return Err(if bytes.len() >= 4 && bytes[..4] != MAGIC {
            FormatError::BadMagic
        } else {
            FormatError::Truncated {
                expected: HEADER,
                got: bytes.len(),
            }
        });
    }
    if bytes[..4] != MAGIC {
        return Err(FormatError::BadMagic);
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let version = u32_at(4);
    let header = match version {
        1 => HEADER_V1,
        VERSION => HEADER,
        _ => return Err(FormatError::UnsupportedVersion(version)),
    };
    if bytes.len() < header {
        return Err(FormatError::Truncated {
            expected: header,
            got: bytes.len(),
        });
    }
    let f32_at = |o: usize| f32::from_bits(u32_at(o));
    let f64_at = |o: usize| f64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    let dims = UVec3::new(u32_at(8), u32_at(12), u32_at(16));
    let (origin, voxel_size) = if version == 1 {
        let o = [f32_at(20), f32_at(24), f32_at(28)].map(f64::from);
        (DVec3::from_array(o), f32_at(32))
    } else {
        (DVec3::new(f64_at(20), f64_at(28), f64_at(36)), f32_at(44))
    };
    let n = dims.x as u128 * dims.y as u128 * dims.z as u128;
    if dims.min_element() < 2 || n > MAX_SAMPLES as u128 {
        return Err(FormatError::BadHeader(format!("dims {dims}")));
    }
    if !origin.is_finite() {
        return Err(FormatError::BadHeader(format!("origin {origin}")));
    }
    if !(voxel_size.is_finite() && voxel_size > 0.0) {
        return Err(FormatError::BadHeader(format!("voxel size {voxel_size}")));
    }
    let margin = if version == 1 { 0.0 } else { f32_at(48) };
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(FormatError::BadHeader(format!("margin {margin}")));
    }
    let expected = header + 2 * n as usize;
    if bytes.len() < expected {
        return Err(FormatError::Truncated {
            expected,
            got: bytes.len(),
        });
    }
    if bytes.len() > expected {
        return Err(FormatError::TrailingBytes(bytes.len() - expected));
    }
    let stored = u32_at(header - 4);
    let computed = crc32(crc32(0, &bytes[..header - 4]), &bytes[header..]);
    if stored != computed {
        return Err(FormatError::ChecksumMismatch { stored, computed });
    }
    let mut data = Vec::with_capacity(n as usize);
    for (index, c) in bytes[header..].chunks_exact(2).enumerate() {
        let s = f16::from_le_bytes([c[0], c[1]]);
        if !s.is_finite() {
            return Err(FormatError::NonFiniteSample { index });
        }
        // Version 1 stored mesh units.
        data.push(if version == 1 {
            SdfVolume::quantize(s.to_f32() / voxel_size)
        } else {
            s
        });
    }
    let mut volume = SdfVolume {
        dims,
        origin,
        voxel_size,
        data,
        margin,
    };
    if version == 1 {
        volume.margin = volume.measured_margin();
    }
    Ok(volume)
}

/// The volume as a `NumPy` `.npy` file: float32, shape `(nz, ny, nx)`, C order, so
/// `a[k, j, i]` is the distance (mesh units) at `origin + voxel_size · (i, j, k)`.
pub fn to_npy(v: &SdfVolume) -> Vec<u8> {
    let mut header = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {}, {}), }}",
        v.dims.z, v.dims.y, v.dims.x
    );
    // Magic (6) + version (2) + header length (2) + header, padded with spaces and a
    // newline to a multiple of 64 bytes.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 4 * v.data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for s in &v.data {
        out.extend_from_slice(&(s.to_f32() * v.voxel_size).to_le_bytes());
    }
    out
}

/// The `.npy` sidecar JSON: `origin` (f64, shortest round-trip digits), `voxel_size`,
/// `dims` (`[nx, ny, nz]`).
pub fn npy_sidecar_json(v: &SdfVolume) -> String {
    format!(
        "{{\"origin\": [{}, {}, {}], \"voxel_size\": {}, \"dims\": [{}, {}, {}]}}\n",
        v.origin.x, v.origin.y, v.origin.z, v.voxel_size, v.dims.x, v.dims.y, v.dims.z
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume() -> SdfVolume {
        SdfVolume {
            dims: UVec3::new(3, 2, 2),
            origin: DVec3::new(-1.0, 0.5, 2.0),
            voxel_size: 0.25,
            data: (0..12)
                .map(|i| f16::from_f32(i as f32 * 0.5 - 3.0))
                .collect(),
            margin: 0.0,
        }
    }

    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(crc32(0, b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn round_trips_bit_exactly() {
        let v = volume();
        assert_eq!(from_bytes(&to_bytes(&v)).unwrap(), v);
    }

    #[test]
    fn corrupt_truncated_and_foreign_files_are_rejected() {
        let good = to_bytes(&volume());
        let mut flipped = good.clone();
        flipped[HEADER + 3] ^= 0x10;
        let mut header_flipped = good.clone();
        header_flipped[21] ^= 0x01; // origin.x
        let mut v3 = good.clone();
        v3[4] = 3;
        let mut zero_dims = good.clone();
        zero_dims[8..12].copy_from_slice(&0u32.to_le_bytes());
        let mut huge_dims = good.clone();
        huge_dims[8..20].copy_from_slice(&[0xff; 12]);
        let mut neg_voxel = good.clone();
        neg_voxel[44..48].copy_from_slice(&(-1.0f32).to_le_bytes());
        let mut nan_margin = good.clone();
        nan_margin[48..52].copy_from_slice(&f32::NAN.to_le_bytes());
        let mut nan_origin = good.clone();
        nan_origin[20..28].copy_from_slice(&f64::NAN.to_le_bytes());
        // A NaN and an infinite sample, with a valid checksum: still rejected.
        let with_sample = |bits: u16| {
            let mut v = volume();
            v.data[5] = f16::from_bits(bits);
            to_bytes(&v)
        };
        let mut trailing = good.clone();
        trailing.push(0);
        type Check = fn(&FormatError) -> bool;
        let cases: Vec<(&str, Vec<u8>, Check)> = vec![
            ("empty", vec![], |e| {
                matches!(e, FormatError::Truncated { .. })
            }),
            ("magic", b"GLTF\x01\x00\x00\x00".to_vec(), |e| {
                *e == FormatError::BadMagic
            }),
            ("header cut", good[..20].to_vec(), |e| {
                matches!(e, FormatError::Truncated { .. })
            }),
            ("data cut", good[..good.len() - 1].to_vec(), |e| {
                matches!(e, FormatError::Truncated { .. })
            }),
            ("trailing", trailing, |e| {
                *e == FormatError::TrailingBytes(1)
            }),
            ("data bit flip", flipped, |e| {
                matches!(e, FormatError::ChecksumMismatch { .. })
            }),
            ("header bit flip", header_flipped, |e| {
                matches!(e, FormatError::ChecksumMismatch { .. })
            }),
            ("version", v3, |e| *e == FormatError::UnsupportedVersion(3)),
            ("nan sample", with_sample(0x7e00), |e| {
                *e == FormatError::NonFiniteSample { index: 5 }
            }),
            ("inf sample", with_sample(0xfc00), |e| {
                *e == FormatError::NonFiniteSample { index: 5 }
            }),
            ("zero dims", zero_dims, |e| {
                matches!(e, FormatError::BadHeader(_))
            }),
            ("huge dims", huge_dims, |e| {
                matches!(e, FormatError::BadHeader(_))
            }),
            ("voxel", neg_voxel, |e| {
                matches!(e, FormatError::BadHeader(_))
            }),
            ("margin", nan_margin, |e| {
                matches!(e, FormatError::BadHeader(_))
            }),
            ("origin", nan_origin, |e| {
                matches!(e, FormatError::BadHeader(_))
            }),
        ];
        for (name, bytes, ok) in cases {
            let e = from_bytes(&bytes).unwrap_err();
            assert!(ok(&e), "{name}: {e:?}");
            assert!(!e.to_string().is_empty());
        }
    }

    /// Version 1 files (f32 origin, samples in mesh units) still load, converted.
    #[test]
    fn version_1_files_are_read_and_converted_to_voxels() {
        let v = volume();
        let mut old = Vec::new();
        old.extend_from_slice(&MAGIC);
        old.extend_from_slice(&1u32.to_le_bytes());
        for d in v.dims.to_array() {
            old.extend_from_slice(&d.to_le_bytes());
        }
        for o in v.origin.to_array() {
            old.extend_from_slice(&(o as f32).to_le_bytes());
        }
        old.extend_from_slice(&v.voxel_size.to_le_bytes());
        old.extend_from_slice(&[0; 4]);
        for i in 0..v.len() {
            old.extend_from_slice(&f16::from_f32(v.data[i].to_f32() * v.voxel_size).to_le_bytes());
        }
        let crc = crc32(crc32(0, &old[..36]), &old[40..]);
        old[36..40].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(from_bytes(&old).unwrap(), v);
    }

    #[test]
    fn npy_header_is_aligned_and_shaped_z_y_x() {
        let v = volume();
        let npy = to_npy(&v);
        assert_eq!(&npy[..8], b"\x93NUMPY\x01\x00");
        let header_len = u16::from_le_bytes([npy[8], npy[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        let header = std::str::from_utf8(&npy[10..10 + header_len]).unwrap();
        assert!(header.contains("'shape': (2, 2, 3)"), "{header}");
        assert!(header.ends_with('\n'));
        assert_eq!(npy.len(), 10 + header_len + 4 * 12);
        // a[1, 0, 2] = sample (i=2, j=0, k=1), in mesh units.
        let at = 10 + header_len + 4 * (2 + 3 * 2);
        let value = f32::from_le_bytes(npy[at..at + 4].try_into().unwrap());
        assert_eq!(value, v.get(2, 0, 1));
        assert_eq!(value, v.get_voxels(2, 0, 1) * 0.25);
        assert!(npy_sidecar_json(&v).contains("\"dims\": [3, 2, 2]"));
    }
}
