//! Animation textures streamed to disk: each `.npy` sheet is an atomic file written a block of
//! frames at a time and hashed on the way ([`TextureFile`]), while the next block is computed
//! ([`stream`]); what each input wrote, with its hash ([`Written`]).

use super::error::InputError;
use super::texture::{self, Precision, TextureKind};
use super::{Animation, Baked};
use crate::device::Device;
use crate::io::{npy_header, AtomicFile, NpyElement};
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::PathBuf;

/// A file an input wrote, with its size and SHA-256 when they were taken as it was written
/// (the textures: hashed from memory while the bytes go to disk, not read back).
pub(super) struct Written {
    pub(super) path: PathBuf,
    pub(super) hash: Option<(u64, String)>,
}

impl From<PathBuf> for Written {
    fn from(path: PathBuf) -> Self {
        Self { path, hash: None }
    }
}

/// Bytes of texture rows computed and written at a time ([`stream`]): large
/// enough that a block is many frames of a small skeleton and a few of a crowd.
const TEXTURE_BLOCK_BYTES: usize = 32 << 20;

/// A `.npy` texture being written atomically a block of rows at a time, hashed on the way (the
/// manifest's SHA-256 without reading the file back).
pub(super) struct TextureFile {
    file: AtomicFile,
    element: NpyElement,
    hasher: Sha256,
    /// Values still to come, and bytes written so far.
    left: u64,
    size: u64,
    /// Bytes of one row (a frame of the sheet), as stored.
    row_bytes: usize,
}

impl TextureFile {
    /// The file at `path` with its header for `shape` written.
    pub(super) fn create(path: PathBuf, precision: Precision, shape: &[u64; 3]) -> Result<Self, InputError> {
        let element = precision.element();
        let file = AtomicFile::create(&path).map_err(|e| InputError::Output(e.to_string()))?;
        let row_bytes = (shape[1] * shape[2]) as usize * element.size();
        let mut texture =
            Self { file, element, hasher: Sha256::new(), left: shape.iter().product(), size: 0, row_bytes };
        texture.write(&npy_header(element.descr(), shape))?;
        Ok(texture)
    }

    /// The file's name (as the sidecar lists it).
    pub(super) fn name(&self) -> String {
        self.file.path().file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
    }

    /// Appends `values` (whole rows), hashed on another core while written.
    pub(super) fn append(&mut self, values: &[f32]) -> Result<(), InputError> {
        self.left = self.left.checked_sub(values.len() as u64).ok_or_else(|| {
            InputError::Internal(format!("{}: more values than its shape holds", self.file.path().display()))
        })?;
        let bytes = self.element.bytes(values);
        self.write(&bytes)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), InputError> {
        let Self { file, hasher, .. } = self;
        let written = std::thread::scope(|s| {
            s.spawn(|| hasher.update(bytes));
            file.write_all(bytes)
        });
        written.map_err(|e| InputError::Output(self.file.error(e).to_string()))?;
        self.size += bytes.len() as u64;
        Ok(())
    }

    /// Commits the file once its shape is filled; what the manifest records of it.
    pub(super) fn finish(self) -> Result<Written, InputError> {
        let path = self.file.path().to_path_buf();
        if self.left != 0 {
            return Err(InputError::Internal(format!("{}: {} values short of its shape", path.display(), self.left)));
        }
        self.file.commit().map_err(|e| InputError::Output(e.to_string()))?;
        Ok(Written { path, hash: Some((self.size, super::manifest::hex(&self.hasher.finalize()))) })
    }
}

/// One [`TextureFile`] per sheet of `kind` ([`texture::layout`]), each `[rows, width,
/// channels]` in `precision`, at `path(suffix)`.
pub(super) fn open(
    animation: &Animation,
    kind: TextureKind,
    precision: Precision,
    rows: usize,
    path: impl Fn(&str) -> PathBuf,
) -> Result<Vec<TextureFile>, InputError> {
    let channels = kind.channels();
    texture::layout(animation, kind)
        .into_iter()
        .map(|(suffix, width)| {
            TextureFile::create(path(&suffix), precision, &[rows as u64, width as u64, channels as u64])
        })
        .collect()
}

/// Computes clip `index`'s sheets of `kind` a block of frames at a time (frames on every core)
/// and appends each block to `textures` on another thread as the next block is computed: the
/// texture is never whole in memory, and the disk writes overlap the arithmetic. Forward
/// kinematics runs on `fk_device`.
pub(super) fn stream(
    kind: TextureKind,
    animation: &Animation,
    baked: &Baked,
    order: &[usize],
    index: usize,
    fk_device: &Device,
    textures: &mut [TextureFile],
) -> Result<(), InputError> {
    let frames = baked.clips[index].times.len();
    let row_bytes = textures.iter().map(|t| t.row_bytes).max().unwrap_or(1).max(1);
    let block = (TEXTURE_BLOCK_BYTES / row_bytes).max(1);
    std::thread::scope(|s| {
        // One block in flight beside the one being computed.
        let (send, receive) = std::sync::mpsc::sync_channel::<Vec<texture::Sheet>>(1);
        let writer = s.spawn(move || -> Result<(), InputError> {
            for sheets in receive {
                for (texture, sheet) in textures.iter_mut().zip(&sheets) {
                    texture.append(&sheet.data)?;
                }
            }
            Ok(())
        });
        let mut computed = Ok(());
        for start in (0..frames).step_by(block) {
            let picks: Vec<usize> = (start..frames.min(start + block)).collect();
            match texture::sheet_rows(animation, order, baked, index, kind, fk_device, &picks) {
                Ok(sheets) => {
                    // A closed channel: the writer failed, and says why below.
                    if send.send(sheets).is_err() {
                        break;
                    }
                }
                Err(e) => {
                    computed = Err(e);
                    break;
                }
            }
        }
        drop(send);
        let written = writer.join().unwrap_or_else(|_| Err(InputError::Internal("the texture writer panicked".into())));
        computed.and(written)
    })
}
