//! Reading track files and writing results: JSON formats of DESIGN section 5, atomic writes,
//! and the built-in demo input.

use crate::output::Output;
use crate::sampling::SampleTimes;
use crate::track::{Track, TrackFile};
use quatcurve_core::quat::{QuatF64, Vec3F64};
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// Why a file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not valid track JSON.
    #[error("{path}: not a valid track file: {source}")]
    Parse {
        /// The file.
        path: String,
        /// Why.
        source: serde_json::Error,
    },
    /// The output could not be written (nothing is left behind).
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Reads a `{"tracks": [...]}` file.
///
/// # Errors
/// [`IoError::Read`] or [`IoError::Parse`], naming the file (and line and column for JSON).
pub fn read_track_file(path: &Path) -> Result<TrackFile, IoError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| IoError::Read { path: name.clone(), source })?;
    serde_json::from_str(&text).map_err(|source| IoError::Parse { path: name, source })
}

/// Writes `bytes` to `path` atomically: a temporary file in the same directory, flushed and
/// renamed over `path`. On any failure the temporary file is removed and `path` is untouched.
/// The file gets the permissions `File::create` would give it (0666 minus the umask), not a
/// temporary file's private 0600, so a shared results directory stays readable by the team.
///
/// # Errors
/// [`IoError::Write`] naming `path`.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<(), IoError> {
    let mut file = AtomicFile::create(path)?;
    write(&mut file).map_err(|source| file.error(source))?;
    file.commit()
}

/// Every temporary file an [`AtomicFile`] makes is named `.quatcurve-<target>.<random>.tmp`,
/// `<target>` the name of the file it becomes (its first [`TEMPORARY_NAME_BYTES`] bytes), so
/// that a job finding one a killed run left knows whose it was ([`temporary_target`]).
pub const TEMPORARY_PREFIX: &str = ".quatcurve-";
/// See [`TEMPORARY_PREFIX`].
const TEMPORARY_SUFFIX: &str = ".tmp";
/// Random characters in a temporary file's name.
const TEMPORARY_RANDOM: usize = 6;
/// The most bytes of the target's name a temporary file's name holds (a file name holds 255).
pub const TEMPORARY_NAME_BYTES: usize = 160;

/// The name of the file the temporary file `name` was to become (its first
/// [`TEMPORARY_NAME_BYTES`] bytes, for a longer one); `None` when `name` is not an
/// [`AtomicFile`]'s.
#[must_use]
pub fn temporary_target(name: &str) -> Option<&str> {
    let middle = name.strip_prefix(TEMPORARY_PREFIX)?.strip_suffix(TEMPORARY_SUFFIX)?;
    let (target, random) = middle.rsplit_once('.')?;
    (random.len() == TEMPORARY_RANDOM && !target.is_empty()).then_some(target)
}

/// A file written atomically as it goes ([`write_atomic`] for a writer that is handed around,
/// as a texture streamed block by block is): bytes go to a temporary file beside `path`, and
/// [`AtomicFile::commit`] flushes, syncs and renames it over `path`. Dropped without a commit
/// (an error on the way), the temporary file is removed and `path` is untouched.
#[derive(Debug)]
pub struct AtomicFile {
    path: std::path::PathBuf,
    out: std::io::BufWriter<tempfile::NamedTempFile>,
}

impl AtomicFile {
    /// The temporary file for `path` (0666 minus the umask, as [`write_atomic`]'s).
    ///
    /// # Errors
    /// [`IoError::Write`] naming `path` when the directory does not take a new file.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir,
            _ => Path::new("."),
        };
        let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let mut end = name.len().min(TEMPORARY_NAME_BYTES);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        let prefix = format!("{TEMPORARY_PREFIX}{}.", &name[..end]);
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(TEMPORARY_SUFFIX).rand_bytes(TEMPORARY_RANDOM);
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let tmp =
            builder.tempfile_in(dir).map_err(|source| IoError::Write { path: path.display().to_string(), source })?;
        Ok(Self { path: path.to_path_buf(), out: std::io::BufWriter::new(tmp) })
    }

    /// The file's path (where it lands on commit).
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `source` as this file's [`IoError::Write`].
    #[must_use]
    pub fn error(&self, source: std::io::Error) -> IoError {
        IoError::Write { path: self.path.display().to_string(), source }
    }

    /// Hands the bytes written so far to the disk without waiting for them (Linux; elsewhere
    /// only the flush), so that the sync in [`Self::commit`] of a large file written block by
    /// block finds little left to wait for.
    ///
    /// # Errors
    /// The flush's.
    #[allow(unsafe_code)]
    pub fn start_writeback(&mut self) -> std::io::Result<()> {
        self.out.flush()?;
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsRawFd;
            let fd = self.out.get_ref().as_file().as_raw_fd();
            // SAFETY: `fd` is this file's open descriptor; SYNC_FILE_RANGE_WRITE only starts
            // writeback of its dirty pages (offset 0, length 0: the whole file) and changes
            // no memory of ours. A failure is harmless: `commit` syncs everything anyway.
            unsafe {
                libc::sync_file_range(fd, 0, 0, libc::SYNC_FILE_RANGE_WRITE);
            }
        }
        Ok(())
    }

    /// Flushes, syncs (the bytes are on disk before the name is) and renames over the path.
    ///
    /// # Errors
    /// [`IoError::Write`] naming the path; the temporary file is removed.
    pub fn commit(self) -> Result<(), IoError> {
        let err = |source| IoError::Write { path: self.path.display().to_string(), source };
        let tmp = self.out.into_inner().map_err(|e| err(e.into_error()))?;
        tmp.as_file().sync_all().map_err(err)?;
        tmp.persist(&self.path).map_err(|e| err(e.error))?;
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.out.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.out.write_all(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// Writes a float32 `.npy` array of the given shape atomically (C order, little-endian).
///
/// # Errors
/// [`IoError::Write`] naming `path`; also when `data` does not fill `shape` exactly.
pub fn write_npy(path: &Path, shape: &[u64], data: &[f32]) -> Result<(), IoError> {
    let npy = Npy::new(NpyElement::F32, shape, data)
        .map_err(|source| IoError::Write { path: path.display().to_string(), source })?;
    write_atomic(path, |w| npy.write(w))
}

/// Writes `data` as a float16 `.npy` array (`<f2`) of the given shape, atomically: each value
/// rounded to the nearest half (about 3 significant digits, range +-65504).
///
/// # Errors
/// As [`write_npy`].
pub fn write_npy_f16(path: &Path, shape: &[u64], data: &[f32]) -> Result<(), IoError> {
    let npy = Npy::new(NpyElement::F16, shape, data)
        .map_err(|source| IoError::Write { path: path.display().to_string(), source })?;
    write_atomic(path, |w| npy.write(w))
}

/// The element type a `.npy` file stores f32 values as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NpyElement {
    /// Little-endian IEEE single (`<f4`).
    F32,
    /// Little-endian IEEE half (`<f2`), each value rounded to the nearest half.
    F16,
}

impl NpyElement {
    /// NumPy's `descr` of the type.
    #[must_use]
    pub fn descr(self) -> &'static str {
        match self {
            NpyElement::F32 => "<f4",
            NpyElement::F16 => "<f2",
        }
    }

    /// Bytes per value.
    #[must_use]
    pub fn size(self) -> usize {
        match self {
            NpyElement::F32 => 4,
            NpyElement::F16 => 2,
        }
    }

    /// `values` as this type's little-endian bytes: borrowed where the floats already are
    /// those bytes (f32 on a little-endian machine), else converted (f16 on every core).
    #[must_use]
    pub fn bytes(self, values: &[f32]) -> std::borrow::Cow<'_, [u8]> {
        use rayon::prelude::*;
        match self {
            NpyElement::F32 if cfg!(target_endian = "little") => {
                std::borrow::Cow::Borrowed(bytemuck::cast_slice(values))
            }
            NpyElement::F32 => std::borrow::Cow::Owned(values.iter().flat_map(|v| v.to_le_bytes()).collect()),
            NpyElement::F16 => {
                let mut body = vec![0u8; 2 * values.len()];
                body.par_chunks_mut(1 << 16).zip(values.par_chunks(1 << 15)).for_each(|(out, values)| {
                    for (o, &v) in out.chunks_exact_mut(2).zip(values) {
                        o.copy_from_slice(&half::f16::from_f32(v).to_le_bytes());
                    }
                });
                std::borrow::Cow::Owned(body)
            }
        }
    }
}

/// The bytes of a `.npy` file, encoded before anything is written.
#[derive(Clone, Debug)]
pub struct Npy<'a> {
    /// The header, byte for byte what `numpy.save` writes.
    pub header: Vec<u8>,
    /// The values ([`NpyElement::bytes`]).
    pub body: std::borrow::Cow<'a, [u8]>,
}

impl<'a> Npy<'a> {
    /// `data` as `element` values of `shape` (C order).
    ///
    /// # Errors
    /// When `data` does not fill `shape` exactly.
    pub fn new(element: NpyElement, shape: &[u64], data: &'a [f32]) -> std::io::Result<Self> {
        check_fill(shape, data.len())?;
        Ok(Self { header: npy_header(element.descr(), shape), body: element.bytes(data) })
    }

    /// Header, then values.
    ///
    /// # Errors
    /// The writer's.
    pub fn write(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(&self.header)?;
        w.write_all(&self.body)
    }

    /// Bytes in the file.
    #[must_use]
    pub fn len(&self) -> usize {
        self.header.len() + self.body.len()
    }

    /// Never: a header is always there.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        false
    }
}

/// The header of a version 1.0 `.npy` file (the NumPy format specification): magic, version,
/// header length, then the array's dict padded with spaces to a multiple of 64 bytes and a
/// newline, byte for byte what `numpy.save` writes. Written here so that the data can follow
/// in whole blocks: npyz's writer takes one value per call, 3.5x slower on the crowd's 350 MB
/// model texture (1.16 s against 0.33 s here). npyz still reads every file in the tests.
#[must_use]
pub fn npy_header(descr: &str, shape: &[u64]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
    let shape = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    let unpadded = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

/// `len` values must fill `shape` exactly.
fn check_fill(shape: &[u64], len: usize) -> std::io::Result<()> {
    if shape.iter().product::<u64>() == len as u64 {
        return Ok(());
    }
    Err(std::io::Error::other(format!("{len} values do not fill shape {shape:?}")))
}

/// Rows of results as JSON. Results a device computed in f32 print each value as the
/// shortest decimal that reads back to the same f32 (`0.70710677`), not as the f64 it was
/// widened to (`0.7071067094802856`, digits the device never computed).
#[derive(Debug)]
pub struct Rows<'a, const N: usize> {
    /// The rows.
    pub rows: &'a [[f64; N]],
    /// Computed in f32.
    pub f32: bool,
}

impl<const N: usize> Serialize for Rows<'_, N> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        struct Row<'a>(&'a [f64], bool);
        impl Serialize for Row<'_> {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                let mut seq = serializer.serialize_seq(Some(self.0.len()))?;
                for &v in self.0 {
                    if self.1 {
                        seq.serialize_element(&(v as f32))?;
                    } else {
                        seq.serialize_element(&v)?;
                    }
                }
                seq.end()
            }
        }
        let mut seq = serializer.serialize_seq(Some(self.rows.len()))?;
        for row in self.rows {
            seq.serialize_element(&Row(row, self.f32))?;
        }
        seq.end()
    }
}

/// One track of the output JSON.
#[derive(Debug, Serialize)]
pub struct TrackResult<'a> {
    /// The input track's name, when it had one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<&'a str>,
    /// The requested times, before clamping.
    pub times: Vec<f64>,
    /// Rotations `[x, y, z, w]`.
    pub rotations: Rows<'a, 4>,
    /// Body angular velocities, with `--derivatives`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angular_velocity: Option<Rows<'a, 3>>,
    /// Body angular accelerations, with `--derivatives`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angular_acceleration: Option<Rows<'a, 3>>,
}

/// The output JSON document (always track-major).
#[derive(Debug, Serialize)]
#[doc(hidden)]
pub struct ResultFile<'a> {
    /// Curve family name.
    pub curve: &'a str,
    /// `reference`, `cpu: <name>` or `gpu: <adapter>`.
    pub device: &'a str,
    /// Per-track results, in input order.
    pub tracks: Vec<TrackResult<'a>>,
}

impl<'a> ResultFile<'a> {
    /// Assembles the document from a track-major [`Output`]; `f32` when the device computed
    /// in f32 (the CPU and GPU paths), so values print as the f32s they are.
    #[must_use]
    pub fn new(
        curve: &'a str,
        device: &'a str,
        tracks: &'a [Track],
        times: &'a SampleTimes,
        out: &'a Output,
        f32: bool,
    ) -> Self {
        let derivs = !out.angular_velocity.is_empty();
        let tracks = tracks
            .iter()
            .enumerate()
            .map(|(i, track)| {
                let range = times.offsets()[i]..times.offsets()[i + 1];
                TrackResult {
                    name: track.name.as_deref(),
                    // As requested: a looping track's own times were wrapped for evaluation.
                    times: track.sample_times.clone().unwrap_or_else(|| times.track_times(i)),
                    rotations: Rows { rows: &out.rotations[range.clone()], f32 },
                    angular_velocity: derivs.then(|| Rows { rows: &out.angular_velocity[range.clone()], f32 }),
                    angular_acceleration: derivs.then(|| Rows { rows: &out.angular_acceleration[range], f32 }),
                }
            })
            .collect();
        Self { curve, device, tracks }
    }
}

/// A small built-in input so the main command runs with no file: three joints of a
/// walk-like loop, 9 keys at 4 Hz, swinging up to 70 degrees with a twist.
#[must_use]
#[doc(hidden)]
pub fn demo_tracks() -> Vec<Track> {
    let joints = [("hips", 0.35, 0.0), ("knee", 0.6, 1.1), ("head", 0.15, 2.3)];
    joints
        .iter()
        .map(|&(name, amplitude, phase)| {
            let times: Vec<f64> = (0..9).map(|i| i as f64 * 0.25).collect();
            let rotations = times
                .iter()
                .map(|&t| {
                    let a = (std::f64::consts::PI * t + phase).sin();
                    let v = Vec3F64::new(amplitude * a, 0.2 * amplitude * (2.0 * a).cos(), 0.1 * phase);
                    QuatF64::exp(v).to_array()
                })
                .collect();
            Track { name: Some(name.to_string()), times: Some(times), ..Track::from_rotations(rotations) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{npy_header, temporary_target, AtomicFile, TEMPORARY_NAME_BYTES};
    use std::io::Write;

    /// A temporary file's name says which file it becomes, so a job can tell its own from
    /// another's; a long name keeps its first bytes on a character boundary.
    #[test]
    fn a_temporary_file_names_the_file_it_becomes() {
        let dir = tempfile::tempdir().unwrap();
        let long = format!("{}.npy", "é".repeat(120));
        for target in ["Fox.Walk.npy", "manifest.0-of-3.json", long.as_str()] {
            let file = AtomicFile::create(&dir.path().join(target)).unwrap();
            let name = file.out.get_ref().path().file_name().unwrap().to_string_lossy().into_owned();
            let named = temporary_target(&name).unwrap_or_else(|| panic!("{name}: not a temporary file's name"));
            if target.len() <= TEMPORARY_NAME_BYTES {
                assert_eq!(named, target);
            } else {
                // "é" is two bytes: the first 160 end on a boundary, kept whole.
                assert!(target.starts_with(named) && named.len() == TEMPORARY_NAME_BYTES, "{name}");
            }
        }
        for other in ["Fox.json", ".quatcurve-.abcdef.tmp", ".quatcurve-Fox.json.tmp", ".quatcurve-Fox.json.abc.tmp"] {
            assert_eq!(temporary_target(other), None, "{other}");
        }
    }

    /// Written in pieces, an atomic file appears whole at commit and not before; dropped
    /// uncommitted (a failed bake), it leaves the directory as it was, an old file included.
    #[test]
    fn atomic_files_appear_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let names = || {
            std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect::<Vec<_>>()
        };
        let path = dir.path().join("texture.npy");
        let mut file = AtomicFile::create(&path).unwrap();
        file.write_all(b"first ").unwrap();
        file.write_all(b"second").unwrap();
        assert!(!path.exists(), "visible before its commit");
        file.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"first second");
        assert_eq!(names(), ["texture.npy"], "a temporary file is left");
        let mut file = AtomicFile::create(&path).unwrap();
        file.write_all(b"half").unwrap();
        drop(file);
        assert_eq!(std::fs::read(&path).unwrap(), b"first second", "an uncommitted file replaced the old one");
        assert_eq!(names(), ["texture.npy"], "an uncommitted file left its temporary behind");
    }

    #[test]
    fn npy_headers_are_what_numpy_save_writes() {
        // From `numpy.save` of a float32 array of shape (301, 24000, 12).
        let numpy = b"\x93NUMPY\x01\x00v\x00{'descr': '<f4', 'fortran_order': False, 'shape': (301, 24000, 12), }                                                \n";
        assert_eq!(npy_header("<f4", &[301, 24000, 12]), numpy);
        for shape in [&[5u64][..], &[], &[1, 2], &[123_456_789, 7, 3, 2]] {
            let header = npy_header("<f2", shape);
            assert_eq!(header.len() % 64, 0, "{shape:?}");
            assert!(header.ends_with(b"\n"));
        }
        assert!(String::from_utf8_lossy(&npy_header("<f2", &[5])).contains("'shape': (5,)"));
    }
}
