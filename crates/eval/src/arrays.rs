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
#[error("{path}: {array}: {rule}")]
pub struct ArrayError {
    /// The file.
    pub path: String,
    /// The array (`rotations`, `times`, ...), or `file`.
    pub array: String,
    /// What is wrong.
    pub rule: ArrayRule,
}

/// The rule an array (or the file holding it) breaks.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ArrayRule {
    /// The file or archive member could not be opened or read.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The archive's directory could not be read, or a member of it.
    #[error("{0}")]
    Zip(#[from] npyz::zip::result::ZipError),
    /// An array the archive must hold.
    #[error("missing: the archive needs a rotations array [tracks, keys, 4]")]
    MissingRotations,
    /// A key rate that is not a positive number.
    #[error("the key rate must be a positive number of keys per second, not {0}")]
    KeyRate(f64),
    /// Times and a key rate both given.
    #[error("the archive has times and a key rate was given; use one")]
    TimesAndKeyRate,
    /// A shape other than the one expected.
    #[error("shape {shape:?}; expected {expected}")]
    Shape {
        /// The array's shape.
        shape: Vec<u64>,
        /// The shapes it may have, in words.
        expected: String,
    },
    /// A shape with no element.
    #[error("shape {0:?} holds no keys")]
    Empty(Vec<u64>),
    /// A shape whose element count overflows.
    #[error("shape {0:?} overflows")]
    Overflow(Vec<u64>),
    /// Fortran order, which would be read transposed.
    #[error("Fortran order; save it C-contiguous (numpy.ascontiguousarray)")]
    Fortran,
    /// A structured dtype.
    #[error("structured dtype; expected float32, float64 or unicode strings")]
    Structured,
    /// A dtype npyz cannot read as the type asked for.
    #[error("{0}")]
    DtypeRead(#[from] npyz::DTypeError),
    /// A dtype other than the ones read.
    #[error("dtype {0}; expected float32 or float64")]
    Dtype(String),
    /// Strings where floats were asked for.
    #[error("holds strings; expected float32 or float64")]
    NotFloats,
    /// Numbers where strings were asked for.
    #[error("holds numbers; expected unicode strings (numpy dtype <U)")]
    NotStrings,
    /// A shape larger than the bytes present (a crafted header could announce any shape).
    #[error("shape {shape:?} of {dtype} needs {needs} bytes, the file holds {holds}")]
    TooLarge {
        /// The array's shape.
        shape: Vec<u64>,
        /// Its dtype, as numpy writes it.
        dtype: String,
        /// Bytes its shape needs.
        needs: u64,
        /// Bytes present.
        holds: u64,
    },
    /// Data that ends before its shape's count.
    #[error("the data ends after {read} of the {count} values its shape says")]
    EndsEarly {
        /// Values read.
        read: usize,
        /// Values its shape says.
        count: usize,
    },
    /// Data that could not be read part way.
    #[error("after {read} values: {error}")]
    Data {
        /// Values read.
        read: usize,
        /// Why the next could not be.
        error: std::io::Error,
    },
    /// A count of values other than its shape's.
    #[error("holds {read} values, its shape says {count}")]
    Count {
        /// Values read.
        read: usize,
        /// Values its shape says.
        count: usize,
    },
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

/// Reads a float32 or float64 array whose data may take at most `budget` bytes (see
/// [`read_tracks`] for why); the rule says what is wrong, for the caller to name the array.
///
/// # Errors
/// Another dtype, a shape larger than the budget, or data that ends early.
pub fn read_floats<R: Read>(npy: NpyFile<R>, budget: u64) -> Result<Floats, ArrayRule> {
    match Member::read(npy, budget)? {
        Member::Floats(f) => Ok(f),
        Member::Strings(..) => Err(ArrayRule::NotFloats),
    }
}

/// Reads the tracks of a `.npy` (rotations only) or `.npz` file. Without `times`, keys are
/// `key_rate` per second from 0 when given, else at `0, 1, ..., n` as in JSON.
///
/// # Errors
/// [`ArrayError`] naming the array for a missing `rotations`, a wrong shape or dtype, a shape
/// larger than the bytes present, or an unreadable file.
pub fn read_tracks(path: &Path, key_rate: Option<f64>) -> Result<Vec<Track>, ArrayError> {
    let err = |array: &str, rule: ArrayRule| ArrayError { path: path.display().to_string(), array: array.into(), rule };
    let file = |e: std::io::Error| err("file", e.into());
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
            let entry = archive.zip_archive().by_name(&file_name).map_err(|e| err(name, e.into()))?;
            let npy = open_npy(entry).map_err(|e| err(name, e.into()))?;
            Ok(Some(Member::read(npy, budget).map_err(|m| err(name, m))?))
        };
        let rotations = member("rotations")?.ok_or_else(|| err("rotations", ArrayRule::MissingRotations))?;
        (
            rotations.floats("rotations", path)?,
            member("times")?.map(|m| m.floats("times", path)).transpose()?,
            member("names")?,
            member("angular_velocities")?.map(|m| m.floats("angular_velocities", path)).transpose()?,
        )
    } else {
        let size = std::fs::metadata(path).map_err(file)?.len();
        let npy = open_npy(std::io::BufReader::new(std::fs::File::open(path).map_err(file)?))
            .map_err(|e| err("rotations", e.into()))?;
        (Member::read(npy, size).map_err(|m| err("rotations", m))?.floats("rotations", path)?, None, None, None)
    };
    match (key_rate, &times) {
        (Some(rate), _) if !(rate.is_finite() && rate > 0.0) => return Err(err("times", ArrayRule::KeyRate(rate))),
        (Some(_), Some(_)) => return Err(err("times", ArrayRule::TimesAndKeyRate)),
        _ => {}
    }
    let [tracks, keys, 4] = rotations.shape[..] else {
        let expected = "[tracks, keys, 4] (x, y, z, w)".into();
        return Err(err("rotations", ArrayRule::Shape { shape: rotations.shape, expected }));
    };
    let (tracks, keys) = (tracks as usize, keys as usize);
    if tracks == 0 || keys == 0 {
        return Err(err("rotations", ArrayRule::Empty(rotations.shape)));
    }
    let times_of = |t: usize| -> Result<Option<Vec<f64>>, ArrayError> {
        Ok(match (&times, key_rate) {
            (Some(times), _) => Some(match times.shape[..] {
                [k] if k as usize == keys => times.data.clone(),
                [n, k] if n as usize == tracks && k as usize == keys => times.data[t * keys..(t + 1) * keys].to_vec(),
                _ => {
                    let expected = format!("[{keys}] or [{tracks}, {keys}] to match rotations");
                    return Err(err("times", ArrayRule::Shape { shape: times.shape.clone(), expected }));
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
            let expected = format!("[{tracks}, {keys}, 3] to match rotations");
            return Err(err("angular_velocities", ArrayRule::Shape { shape: v.shape.clone(), expected }));
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
    fn read<R: Read>(npy: NpyFile<R>, budget: u64) -> Result<Self, ArrayRule> {
        let shape = npy.shape().to_vec();
        let Some(count) = shape.iter().try_fold(1u64, |a, &d| a.checked_mul(d)) else {
            return Err(ArrayRule::Overflow(shape));
        };
        // Fortran order would be read transposed without a word.
        if npy.order() == npyz::Order::Fortran && shape.iter().filter(|&&d| d > 1).count() > 1 {
            return Err(ArrayRule::Fortran);
        }
        let DType::Plain(ty) = npy.dtype() else {
            return Err(ArrayRule::Structured);
        };
        let needs = count.saturating_mul(ty.num_bytes().unwrap_or(0) as u64);
        if needs > budget {
            return Err(ArrayRule::TooLarge { shape, dtype: ty.to_string(), needs, holds: budget });
        }
        let capacity = count as usize;
        match (ty.type_char(), ty.size_field()) {
            (TypeChar::Float, 8) => Ok(Self::Floats(Floats { shape, data: collect(npy.data::<f64>()?, capacity)? })),
            (TypeChar::Float, 4) => {
                let data: Vec<f32> = collect(npy.data::<f32>()?, capacity)?;
                Ok(Self::Floats(Floats { shape, data: data.into_iter().map(f64::from).collect() }))
            }
            (TypeChar::UnicodeStr, _) => {
                let chars: Vec<Vec<char>> = collect(npy.data::<Vec<char>>()?, capacity)?;
                Ok(Self::Strings(shape, chars.into_iter().map(|c| c.into_iter().collect()).collect()))
            }
            _ => Err(ArrayRule::Dtype(ty.to_string())),
        }
    }

    fn floats(self, array: &str, path: &Path) -> Result<Floats, ArrayError> {
        match self {
            Self::Floats(f) => Ok(f),
            Self::Strings(..) => {
                Err(ArrayError { path: path.display().to_string(), array: array.into(), rule: ArrayRule::NotFloats })
            }
        }
    }

    fn strings(self, array: &str, tracks: usize, path: &Path) -> Result<Vec<String>, ArrayError> {
        let err = |rule: ArrayRule| ArrayError { path: path.display().to_string(), array: array.into(), rule };
        match self {
            Self::Strings(shape, names) if shape[..] == [tracks as u64] => Ok(names),
            Self::Strings(shape, _) => {
                Err(err(ArrayRule::Shape { shape, expected: format!("[{tracks}] to match rotations") }))
            }
            Self::Floats(_) => Err(err(ArrayRule::NotStrings)),
        }
    }
}

/// Collects a reader's items, growing with the data actually read.
fn collect<T>(items: impl Iterator<Item = std::io::Result<T>>, count: usize) -> Result<Vec<T>, ArrayRule> {
    let mut out = Vec::with_capacity(count.min(1 << 20));
    for item in items {
        out.push(item.map_err(|error| match error.kind() {
            std::io::ErrorKind::UnexpectedEof => ArrayRule::EndsEarly { read: out.len(), count },
            _ => ArrayRule::Data { read: out.len(), error },
        })?);
    }
    if out.len() != count {
        return Err(ArrayRule::Count { read: out.len(), count });
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
