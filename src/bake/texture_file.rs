//! Animation textures written as they are computed: each sheet is an atomic file, a `.npy`
//! written a block of frames at a time, hashed on the way and each block handed to the disk
//! as the next is computed (the final sync then waits for little), or an image gathered and encoded
//! at the end ([`TextureFile`]), while the next block is computed ([`stream`]); what each input
//! wrote, with its hash ([`Written`]).

use super::error::InputError;
use super::image::{self, Format, Grid};
use super::texture::{self, Precision, TextureKind};
use super::{Animation, Baked};
use crate::device::Device;
use crate::io::{npy_header, AtomicFile, NpyElement};
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::PathBuf;

/// A file an input wrote, with its size and SHA-256 when they were taken as it was written
/// (the textures: hashed from memory while the bytes go to disk, not read back), and for an
/// image texture where its texels are.
pub(super) struct Written {
    pub(super) path: PathBuf,
    pub(super) hash: Option<(u64, String)>,
    pub(super) image: Option<ImageTexture>,
}

impl From<PathBuf> for Written {
    fn from(path: PathBuf) -> Self {
        Self { path, hash: None, image: None }
    }
}

/// What a renderer needs to read an image texture: its grid, the joints per frame, and for
/// PNG16 the range each channel of each texel slot was mapped from.
#[derive(Clone, Debug)]
pub(super) struct ImageTexture {
    pub(super) grid: Grid,
    pub(super) joints: usize,
    pub(super) remap: Option<Vec<[[f32; 2]; 4]>>,
}

/// Bytes of texture rows computed and written at a time ([`stream`]): large
/// enough that a block is many frames of a small skeleton and a few of a crowd.
const TEXTURE_BLOCK_BYTES: usize = 32 << 20;

/// A texture being written atomically a block of rows at a time: a `.npy` file streamed to disk
/// and hashed on the way (the manifest's SHA-256 without reading the file back), or an image
/// (EXR, PNG16) gathered in memory and encoded when its rows are complete.
pub(super) struct TextureFile {
    file: AtomicFile,
    content: Content,
    hasher: Sha256,
    /// Values still to come, and bytes written so far.
    left: u64,
    size: u64,
    /// Bytes of one row (a frame of the sheet), as gathered.
    row_bytes: usize,
}

/// What a [`TextureFile`] holds until it is finished.
enum Content {
    /// Rows go straight to the `.npy` file in this element type.
    Npy(NpyElement),
    /// Rows gathered for an image of `kind` texels on `grid`.
    Image { format: Format, kind: TextureKind, half: bool, grid: Grid, joints: usize, rows: Vec<f32> },
}

/// How a bake's textures are written: their format, element type, kind and largest side.
#[derive(Clone, Copy, Debug)]
pub(super) struct TextureOptions {
    pub(super) format: Format,
    pub(super) precision: Precision,
    pub(super) kind: TextureKind,
    pub(super) max_size: usize,
}

impl TextureFile {
    /// The texture at `path` for `shape` (`[rows, joints, channels]`); an image's grid is laid
    /// out here, so a texture that cannot fit is refused before any row is computed (`what`
    /// names it in the message).
    pub(super) fn create(
        path: PathBuf,
        options: &TextureOptions,
        shape: &[u64; 3],
        what: &str,
    ) -> Result<Self, InputError> {
        let [rows, joints, channels] = shape.map(|n| n as usize);
        let content = match options.format {
            Format::Npy => Content::Npy(options.precision.element()),
            format => {
                let grid = Grid::new(options.kind, joints, rows, options.max_size)
                    .map_err(|e| InputError::Animation(format!("{what}: {e}")))?;
                let half = options.precision == Precision::F16;
                Content::Image { format, kind: options.kind, half, grid, joints, rows: Vec::new() }
            }
        };
        let file = AtomicFile::create(&path).map_err(|e| InputError::Output(e.to_string()))?;
        let element_bytes = match content {
            Content::Npy(element) => element.size(),
            Content::Image { .. } => 4,
        };
        let mut texture = Self {
            file,
            content,
            hasher: Sha256::new(),
            left: shape.iter().product(),
            size: 0,
            row_bytes: joints * channels * element_bytes,
        };
        if let Content::Npy(element) = texture.content {
            texture.write(&npy_header(element.descr(), shape))?;
        }
        Ok(texture)
    }

    /// The file's name (as the sidecar lists it).
    pub(super) fn name(&self) -> String {
        self.file.path().file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
    }

    /// Appends `values` (whole rows): written and hashed on another core, or gathered.
    pub(super) fn append(&mut self, values: &[f32]) -> Result<(), InputError> {
        self.left = self.left.checked_sub(values.len() as u64).ok_or_else(|| {
            InputError::Internal(format!("{}: more values than its shape holds", self.file.path().display()))
        })?;
        match &mut self.content {
            Content::Npy(element) => {
                let bytes = element.bytes(values);
                self.write(&bytes)
            }
            Content::Image { rows, .. } => {
                rows.extend_from_slice(values);
                Ok(())
            }
        }
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), InputError> {
        let Self { file, hasher, .. } = self;
        let written = std::thread::scope(|s| {
            s.spawn(|| hasher.update(bytes));
            file.write_all(bytes)?;
            file.start_writeback()
        });
        written.map_err(|e| InputError::Output(self.file.error(e).to_string()))?;
        self.size += bytes.len() as u64;
        Ok(())
    }

    /// Commits the file once its shape is filled (an image encoded first); what the manifest
    /// and the sidecar record of it.
    pub(super) fn finish(mut self) -> Result<Written, InputError> {
        let path = self.file.path().to_path_buf();
        if self.left != 0 {
            return Err(InputError::Internal(format!("{}: {} values short of its shape", path.display(), self.left)));
        }
        let image = match std::mem::replace(&mut self.content, Content::Npy(NpyElement::F32)) {
            Content::Npy(_) => None,
            Content::Image { format, kind, half, grid, joints, rows } => {
                let texels = image::texels(kind, &grid, joints, &rows);
                let internal = |e: String| InputError::Internal(format!("{}: {e}", path.display()));
                let (bytes, remap) = match format {
                    Format::Exr => (image::exr(&grid, &texels, half).map_err(internal)?, None),
                    #[cfg(feature = "plot")]
                    Format::Png16 => {
                        let remap = image::ranges(kind, &rows);
                        (image::png16(&grid, &texels, &remap).map_err(internal)?, Some(remap))
                    }
                    _ => {
                        return Err(InputError::Internal(format!(
                            "{}: no encoder for {format} in this build",
                            path.display()
                        )))
                    }
                };
                self.write(&bytes)?;
                Some(ImageTexture { grid, joints, remap })
            }
        };
        self.file.commit().map_err(|e| InputError::Output(e.to_string()))?;
        Ok(Written { path, hash: Some((self.size, super::manifest::hex(&self.hasher.finalize()))), image })
    }
}

/// One [`TextureFile`] per sheet of `options.kind` ([`texture::layout`]), each `[rows,
/// width, channels]`, at `path(suffix)`; `what` names the texture in messages.
pub(super) fn open(
    animation: &Animation,
    options: &TextureOptions,
    rows: usize,
    what: &str,
    path: impl Fn(&str) -> PathBuf,
) -> Result<Vec<TextureFile>, InputError> {
    let channels = options.kind.channels();
    texture::layout(animation, options.kind)
        .into_iter()
        .map(|(suffix, width)| {
            TextureFile::create(path(&suffix), options, &[rows as u64, width as u64, channels as u64], what)
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
        let mut signs = texture::Signs::default();
        for start in (0..frames).step_by(block) {
            let picks: Vec<usize> = (start..frames.min(start + block)).collect();
            match texture::sheet_rows(animation, order, baked, index, kind, fk_device, &picks) {
                Ok(mut sheets) => {
                    signs.follow(kind, &mut sheets);
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
