//! Tracks from numpy arrays (`eval --input tracks.npz|tracks.npy`), for batches too large
//! for JSON: `rotations` `[tracks, keys, 4]` (x, y, z, w), optional `times` `[keys]` or
//! `[tracks, keys]`, `names` `[tracks]` (unicode strings) and `angular_velocities`
//! `[tracks, keys, 3]`. A `.npy` file holds `rotations` alone.
//!
//! Shapes come from the file, so none sizes an allocation before it is checked against the
//! bytes present (a crafted header could announce any shape).

use crate::track::Track;
use npyz::{DType, NpyFile, TypeChar};
use std::io::{Cursor, Read};
use std::path::Path;

/// Why arrays could not be read as tracks: the file, the array and the rule broken.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {array}: {message}")]
pub struct ArrayError {
    /// The file.
    pub path: String,
    /// The array (`rotations`, `times`, ...), or `file`.
    pub array: String,
    /// What is wrong.
    pub message: String,
}

/// Compressed data may expand at most this much (deflate's own limit is about 1032:1), so a
/// small archive cannot claim gigabytes.
const MAX_EXPANSION: u64 = 1100;

/// The most bytes an archive member of `size` bytes as its entry claims, stored in
/// `compressed` bytes, may be read as: what deflate can expand that to, and never more.
#[must_use]
pub fn member_budget(size: u64, compressed: u64) -> u64 {
    size.min(compressed.saturating_mul(MAX_EXPANSION).saturating_add(1 << 20))
}

/// A float array: shape and values in C order.
#[derive(Clone, Debug, PartialEq)]
pub struct Floats {
    /// The array's shape.
    pub shape: Vec<u64>,
    /// Its values, widened to f64.
    pub data: Vec<f64>,
}

/// The most header bytes a `.npy` may announce (numpy writes under 100; its own reader takes
/// at most 10,000 unless told otherwise).
const MAX_HEADER: usize = 1 << 16;

/// A `.npy` array from `reader`, its header read here first: a shape whose element count
/// overflows is refused before npyz multiplies it out (npyz's product overflows; found by
/// the mutation tests).
///
/// # Errors
/// A short or oversized header, an overflowing shape, or npyz's own refusals.
pub fn open_npy<R: Read>(mut reader: R) -> std::io::Result<NpyFile<std::io::Chain<Cursor<Vec<u8>>, R>>> {
    let invalid = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidData, m);
    // Magic (6 bytes), version (2), header length (2 bytes in version 1, 4 after).
    let mut head = vec![0u8; 10];
    reader.read_exact(&mut head)?;
    let length = if head[6] == 1 {
        usize::from(u16::from_le_bytes([head[8], head[9]]))
    } else {
        head.extend([0, 0]);
        reader.read_exact(&mut head[10..])?;
        u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize
    };
    if length > MAX_HEADER {
        return Err(invalid(format!("a header of {length} bytes; .npy headers are under {MAX_HEADER}")));
    }
    let start = head.len();
    head.resize(start + length, 0);
    reader.read_exact(&mut head[start..])?;
    if let Some(shape) = shape_text(&head[start..]) {
        let dims: Option<Vec<u64>> =
            shape.split(',').map(str::trim).filter(|d| !d.is_empty()).map(|d| d.parse().ok()).collect();
        if dims.is_some_and(|d| d.iter().try_fold(1u64, |a, &n| a.checked_mul(n)).is_none()) {
            return Err(invalid(format!("shape ({shape}) overflows")));
        }
    }
    NpyFile::new(Cursor::new(head).chain(reader))
}

/// The text between the parentheses of a header's `'shape'` entry.
fn shape_text(header: &[u8]) -> Option<&str> {
    let text = std::str::from_utf8(header).ok()?;
    let after = &text[text.find("shape")?..];
    let open = after.find('(')?;
    let close = after[open..].find(')')?;
    Some(&after[open + 1..open + close])
}

/// Why an array of strings is not the floats asked for.
const NOT_FLOATS: &str = "holds strings; expected float32 or float64";

/// Reads a float32 or float64 array whose data may take at most `budget` bytes (see
/// [`read_tracks`] for why); the message says what is wrong, for the caller to name the array.
///
/// # Errors
/// Another dtype, a shape larger than the budget, or data that ends early.
pub fn read_floats<R: Read>(npy: NpyFile<R>, budget: u64) -> Result<Floats, String> {
    match Member::read(npy, budget)? {
        Member::Floats(f) => Ok(f),
        Member::Strings(..) => Err(NOT_FLOATS.into()),
    }
}

/// Reads the tracks of a `.npy` (rotations only) or `.npz` file. Without `times`, keys are
/// `key_rate` per second from 0 when given, else at `0, 1, ..., n` as in JSON.
///
/// # Errors
/// [`ArrayError`] naming the array for a missing `rotations`, a wrong shape or dtype, a shape
/// larger than the bytes present, or an unreadable file.
pub fn read_tracks(path: &Path, key_rate: Option<f64>) -> Result<Vec<Track>, ArrayError> {
    let err =
        |array: &str, message: String| ArrayError { path: path.display().to_string(), array: array.into(), message };
    let file = |e: std::io::Error| err("file", e.to_string());
    let is_npz = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npz"));
    let (rotations, times, names, velocities) = if is_npz {
        let mut archive = npyz::npz::NpzArchive::open(path).map_err(file)?;
        let mut member = |name: &str| -> Result<Option<Member>, ArrayError> {
            let file_name = npyz::npz::file_name_from_array_name(name);
            let (size, compressed) = match archive.zip_archive().by_name(&file_name) {
                Ok(entry) => (entry.size(), entry.compressed_size()),
                Err(_) => return Ok(None),
            };
            let budget = member_budget(size, compressed);
            let entry = archive.zip_archive().by_name(&file_name).map_err(|e| err(name, e.to_string()))?;
            let npy = open_npy(entry).map_err(|e| err(name, e.to_string()))?;
            Ok(Some(Member::read(npy, budget).map_err(|m| err(name, m))?))
        };
        let rotations = member("rotations")?
            .ok_or_else(|| err("rotations", "missing: the archive needs a rotations array [tracks, keys, 4]".into()))?;
        (
            rotations.floats("rotations", path)?,
            member("times")?.map(|m| m.floats("times", path)).transpose()?,
            member("names")?,
            member("angular_velocities")?.map(|m| m.floats("angular_velocities", path)).transpose()?,
        )
    } else {
        let size = std::fs::metadata(path).map_err(file)?.len();
        let npy = open_npy(std::io::BufReader::new(std::fs::File::open(path).map_err(file)?))
            .map_err(|e| err("rotations", e.to_string()))?;
        (Member::read(npy, size).map_err(|m| err("rotations", m))?.floats("rotations", path)?, None, None, None)
    };
    match (key_rate, &times) {
        (Some(rate), _) if !(rate.is_finite() && rate > 0.0) => {
            return Err(err("times", format!("the key rate must be a positive number of keys per second, not {rate}")))
        }
        (Some(_), Some(_)) => {
            return Err(err("times", "the archive has times and a key rate was given; use one".into()))
        }
        _ => {}
    }
    let [tracks, keys, 4] = rotations.shape[..] else {
        return Err(err("rotations", format!("shape {:?}; expected [tracks, keys, 4] (x, y, z, w)", rotations.shape)));
    };
    let (tracks, keys) = (tracks as usize, keys as usize);
    if tracks == 0 || keys == 0 {
        return Err(err("rotations", format!("shape {:?} holds no keys", rotations.shape)));
    }
    let times_of = |t: usize| -> Result<Option<Vec<f64>>, ArrayError> {
        Ok(match (&times, key_rate) {
            (Some(times), _) => Some(match times.shape[..] {
                [k] if k as usize == keys => times.data.clone(),
                [n, k] if n as usize == tracks && k as usize == keys => times.data[t * keys..(t + 1) * keys].to_vec(),
                _ => {
                    return Err(err(
                        "times",
                        format!("shape {:?}; expected [{keys}] or [{tracks}, {keys}] to match rotations", times.shape),
                    ))
                }
            }),
            (None, Some(rate)) => Some((0..keys).map(|k| k as f64 / rate).collect()),
            (None, None) => None,
        })
    };
    let names = match names {
        Some(m) => Some(m.strings("names", tracks, path)?),
        None => None,
    };
    if let Some(v) = &velocities {
        if v.shape[..] != [tracks as u64, keys as u64, 3] {
            return Err(err(
                "angular_velocities",
                format!("shape {:?}; expected [{tracks}, {keys}, 3] to match rotations", v.shape),
            ));
        }
    }
    (0..tracks)
        .map(|t| {
            let rows = &rotations.data[t * keys * 4..(t + 1) * keys * 4];
            Ok(Track {
                name: names.as_ref().map(|n| n[t].clone()),
                times: times_of(t)?,
                rotations: rows.chunks_exact(4).map(|q| [q[0], q[1], q[2], q[3]]).collect(),
                angular_velocities: velocities.as_ref().map(|v| {
                    v.data[t * keys * 3..(t + 1) * keys * 3].chunks_exact(3).map(|w| [w[0], w[1], w[2]]).collect()
                }),
                ..Track::default()
            })
        })
        .collect()
}

/// One array as read: floats, or unicode strings.
enum Member {
    Floats(Floats),
    Strings(Vec<u64>, Vec<String>),
}

impl Member {
    /// Reads an array of float32/float64 or unicode strings whose data may take at most
    /// `budget` bytes; elements are pushed as they are read, never preallocated from the shape.
    fn read<R: Read>(npy: NpyFile<R>, budget: u64) -> Result<Self, String> {
        let shape = npy.shape().to_vec();
        let count = shape
            .iter()
            .try_fold(1u64, |a, &d| a.checked_mul(d))
            .ok_or_else(|| format!("shape {shape:?} overflows"))?;
        // Fortran order would be read transposed without a word.
        if npy.order() == npyz::Order::Fortran && shape.iter().filter(|&&d| d > 1).count() > 1 {
            return Err("Fortran order; save it C-contiguous (numpy.ascontiguousarray)".into());
        }
        let DType::Plain(ty) = npy.dtype() else {
            return Err("structured dtype; expected float32, float64 or unicode strings".into());
        };
        let item = ty.num_bytes().unwrap_or(0) as u64;
        if count.saturating_mul(item) > budget {
            return Err(format!(
                "shape {shape:?} of {ty} needs {} bytes, the file holds {budget}",
                count.saturating_mul(item)
            ));
        }
        let capacity = count as usize;
        match (ty.type_char(), ty.size_field()) {
            (TypeChar::Float, 8) => Ok(Self::Floats(Floats {
                shape,
                data: collect(npy.data::<f64>().map_err(|e| e.to_string())?, capacity)?,
            })),
            (TypeChar::Float, 4) => {
                let data: Vec<f32> = collect(npy.data::<f32>().map_err(|e| e.to_string())?, capacity)?;
                Ok(Self::Floats(Floats { shape, data: data.into_iter().map(f64::from).collect() }))
            }
            (TypeChar::UnicodeStr, _) => {
                let chars: Vec<Vec<char>> = collect(npy.data::<Vec<char>>().map_err(|e| e.to_string())?, capacity)?;
                Ok(Self::Strings(shape, chars.into_iter().map(|c| c.into_iter().collect()).collect()))
            }
            _ => Err(format!("dtype {ty}; expected float32 or float64")),
        }
    }

    fn floats(self, array: &str, path: &Path) -> Result<Floats, ArrayError> {
        match self {
            Self::Floats(f) => Ok(f),
            Self::Strings(..) => {
                Err(ArrayError { path: path.display().to_string(), array: array.into(), message: NOT_FLOATS.into() })
            }
        }
    }

    fn strings(self, array: &str, tracks: usize, path: &Path) -> Result<Vec<String>, ArrayError> {
        let err = |message: String| ArrayError { path: path.display().to_string(), array: array.into(), message };
        match self {
            Self::Strings(shape, names) if shape[..] == [tracks as u64] => Ok(names),
            Self::Strings(shape, _) => Err(err(format!("shape {shape:?}; expected [{tracks}] to match rotations"))),
            Self::Floats(_) => Err(err("holds numbers; expected unicode strings (numpy dtype <U)".into())),
        }
    }
}

/// Collects a reader's items, growing with the data actually read.
fn collect<T>(items: impl Iterator<Item = std::io::Result<T>>, count: usize) -> Result<Vec<T>, String> {
    let mut out = Vec::with_capacity(count.min(1 << 20));
    for item in items {
        out.push(item.map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => {
                format!("the data ends after {} of the {count} values its shape says", out.len())
            }
            _ => format!("after {} values: {e}", out.len()),
        })?);
    }
    if out.len() != count {
        return Err(format!("holds {} values, its shape says {count}", out.len()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::npy_header;

    fn npy(descr: &str, shape: &[u64], data: &[f64]) -> Vec<u8> {
        let mut bytes = npy_header(descr, shape);
        bytes.extend(data.iter().flat_map(|v| v.to_le_bytes()));
        bytes
    }

    #[test]
    fn headers_are_checked_before_npyz_multiplies_the_shape_out() {
        let read = |bytes: &[u8]| {
            open_npy(bytes).and_then(|f| read_floats(f, bytes.len() as u64).map_err(std::io::Error::other))
        };
        assert_eq!(read(&npy("<f8", &[2, 1], &[1.0, 2.0])).unwrap().data, [1.0, 2.0]);
        let overflow = read(&npy("<f8", &[1 << 32, 1 << 32, 2], &[0.0])).unwrap_err().to_string();
        assert_eq!(overflow, "shape (4294967296, 4294967296, 2) overflows");
        let mut huge = npy("<f8", &[1], &[0.0]);
        huge[8..10].copy_from_slice(&u16::MAX.to_le_bytes());
        assert!(read(&huge).is_err());
        let mut long = b"\x93NUMPY\x02\x00".to_vec();
        long.extend(u32::MAX.to_le_bytes());
        assert!(read(&long).unwrap_err().to_string().contains("a header of 4294967295 bytes"));
        let mut fortran = npy("<f8", &[2, 2], &[0.0; 4]);
        let at = fortran.windows(5).position(|w| w == b"False").unwrap();
        fortran[at..at + 5].copy_from_slice(b"True ");
        let refused = read(&fortran).unwrap_err().to_string();
        assert!(refused.contains("Fortran order"), "{refused}");
    }
}
