//! Float32 `.npy` files (`NumPy` format 1.0, C order): the scene viewer's `--dump`
//! buffers and the truth computed for them ([`crate::scene_truth`]).

use std::io::Write;
use std::path::Path;

/// Writes `data` as a float32 array of `shape` (row-major).
pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) -> std::io::Result<()> {
    if shape.iter().product::<usize>() != data.len() {
        return Err(std::io::Error::other(format!(
            "{}: shape {shape:?} does not hold {} values",
            path.display(),
            data.len()
        )));
    }
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    file.write_all(b"\x93NUMPY\x01\x00")?;
    file.write_all(&(header.len() as u16).to_le_bytes())?;
    file.write_all(header.as_bytes())?;
    for v in data {
        file.write_all(&v.to_le_bytes())?;
    }
    file.flush()
}

/// Reads a little-endian float32 C-order array: `(shape, values)`.
pub fn read_f32(path: &Path) -> Result<(Vec<usize>, Vec<f32>), String> {
    let shown = path.display();
    let bytes = std::fs::read(path).map_err(|e| format!("{shown}: {e}"))?;
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" || bytes[6] != 1 {
        return Err(format!("{shown}: not a version 1 .npy file"));
    }
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = bytes
        .get(10..10 + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| format!("{shown}: truncated header"))?;
    if !header.contains("'descr': '<f4'") || !header.contains("'fortran_order': False") {
        return Err(format!("{shown}: not little-endian float32 in C order"));
    }
    let shape: Vec<usize> = header
        .split_once("'shape': (")
        .and_then(|(_, s)| s.split_once(')'))
        .ok_or_else(|| format!("{shown}: no shape"))?
        .0
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let data: Vec<f32> = bytes[10 + len..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if shape.iter().product::<usize>() != data.len() {
        return Err(format!(
            "{shown}: shape {shape:?} but {} values",
            data.len()
        ));
    }
    Ok((shape, data))
}

#[cfg(test)]
mod tests {
    #[test]
    fn arrays_round_trip_and_bad_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("penumbra_npy_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.npy");
        let data = [1.0, f32::NAN, -2.5, 0.0, 3.0, 7.0];
        super::write_f32(&path, &[2, 3], &data).unwrap();
        // The header is padded so that the data starts on a 64-byte boundary.
        let bytes = std::fs::read(&path).unwrap();
        let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + len) % 64, 0);
        assert_eq!(bytes.len(), 10 + len + 4 * data.len());
        let (shape, back) = super::read_f32(&path).unwrap();
        assert_eq!(shape, [2, 3]);
        assert!(
            data.iter()
                .zip(&back)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert!(super::write_f32(&path, &[4], &data).is_err());
        std::fs::write(&path, b"\x93NUMPY\x01\x00\xff\x00{'descr'").unwrap();
        assert!(super::read_f32(&path).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
