//! Animation textures written as they are computed: each sheet is an atomic file, a `.npy`
//! written a block of frames at a time, hashed on the way and each block handed to the disk
//! as the next is computed (the final sync then waits for little), or an image gathered and encoded
//! at the end ([`TextureFile`]), while the next block is computed ([`stream`]); what each input
//! wrote, with its hash ([`Written`]).
use super::babylon;
use super::image::{self, Format, Grid, ImageError, Texels};
use super::texture::{self, Precision, TextureKind};
use super::vertex_encoding::Bounds;
use crate::error::{BakeError, Refusal};
use quatcurve_anim::error::{InputError, InternalError, OutputError};
use quatcurve_anim::Animation;
use quatcurve_eval::io::{npy_header, AtomicFile, NpyElement};
use quatcurve_eval::skeleton::Affine;
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

/// What a renderer needs to read an image texture: its grid, the joints (or vertices) per
/// frame, for a bone texture's PNG16 the range each channel of each texel slot was mapped
/// from, and for a vertex texture's positions the box they were remapped into.
#[derive(Clone, Debug)]
pub(super) struct ImageTexture {
    pub(super) grid: Grid,
    pub(super) joints: usize,
    pub(super) remap: Option<Vec<[[f32; 2]; 4]>>,
    pub(super) bounds: Option<Bounds>,
}

/// One file of a texture: its name's suffix, what it holds in words (for messages), joints
/// (or vertices) per frame, and what its rows hold ([`Texels`]: their floats per joint, and
/// how an image of them is made).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct SheetSpec {
    pub(super) suffix: String,
    pub(super) label: String,
    pub(super) width: usize,
    pub(super) texels: Texels,
    /// `--format babylon`: the skin matrices are written in this space
    /// ([`babylon::from_world`] of the node Babylon hangs the mesh from).
    pub(super) babylon: Option<Affine>,
}

/// The files of a bone texture of `kind` ([`texture::layout`]); for `--format babylon`, with
/// each skin's space (`babylon`, one per skin).
pub(super) fn bone_sheets(animation: &Animation, kind: TextureKind, babylon: &[Affine]) -> Vec<SheetSpec> {
    texture::layout(animation, kind)
        .into_iter()
        .enumerate()
        .map(|(k, (suffix, width))| {
            let label = match suffix.strip_prefix('.') {
                Some(skin) => format!("the {kind} texture of {skin}"),
                None => format!("the {kind} texture"),
            };
            SheetSpec { suffix, label, width, texels: Texels::Rows(kind), babylon: babylon.get(k).copied() }
        })
        .collect()
}

/// The most memory an image texture may hold while its rows are gathered (its floats, then
/// its texels), and the most the images of one clip (or atlas) may gather together: images
/// are encoded whole, so larger ones are refused before any row is computed. `.npy` textures
/// are streamed and have no such limit.
pub const IMAGE_MEMORY_LIMIT: u64 = 1 << 30;

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
    /// Rows gathered for an image of `texels` on `grid`.
    Image { format: Format, texels: Texels, half: bool, grid: Grid, joints: usize, rows: Vec<f32> },
    /// Skin matrices gathered for Babylon's JSON, written in the space `from_world`.
    Babylon { from_world: Affine, bones: usize, rows: Vec<f32> },
}

/// How a bake's textures are written: their format, element type and largest side.
#[derive(Clone, Copy, Debug)]
pub(super) struct TextureOptions {
    pub(super) format: Format,
    pub(super) precision: Precision,
    pub(super) max_size: usize,
}

impl TextureFile {
    /// The texture at `path` of `rows` rows of `sheet`; an image's grid is laid out and its
    /// memory checked here, so a texture that cannot be made is refused before any row is
    /// computed (`what` names it in the message).
    pub(super) fn create(
        path: PathBuf,
        options: &TextureOptions,
        sheet: &SheetSpec,
        rows: usize,
        what: &str,
    ) -> Result<Self, BakeError> {
        let (joints, channels) = (sheet.width, sheet.texels.channels());
        let shape = [rows as u64, joints as u64, channels as u64];
        let content = match options.format {
            Format::Npy => Content::Npy(options.precision.element()),
            Format::Babylon => {
                let from_world = sheet.babylon.expect("every sheet of a Babylon bake has its space");
                if let Some(error) = babylon::too_large(joints, rows, options.max_size) {
                    return Err(
                        Refusal::BabylonTooLarge { texture: what.into(), sheet: sheet.label.clone(), error }.into()
                    );
                }
                Content::Babylon { from_world, bones: joints, rows: Vec::new() }
            }
            format => {
                let kind = match sheet.texels {
                    Texels::Rows(kind) => kind,
                    Texels::Positions | Texels::Normals => TextureKind::Vertex,
                };
                let grid = Grid::new(kind, joints, rows, options.max_size)
                    .map_err(|error| Refusal::Image { texture: what.into(), error })?;
                let floats = shape.iter().product::<u64>() * 4;
                let texels = (grid.width * grid.height) as u64 * 16;
                if floats + texels > IMAGE_MEMORY_LIMIT {
                    return Err(Refusal::ImageMemory {
                        texture: what.into(),
                        format: format.name(),
                        file: path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
                        mib: (floats + texels).div_ceil(1 << 20),
                        limit: IMAGE_MEMORY_LIMIT,
                    }
                    .into());
                }
                let half = options.precision == Precision::F16;
                Content::Image { format, texels: sheet.texels, half, grid, joints, rows: Vec::new() }
            }
        };
        let file = AtomicFile::create(&path).map_err(OutputError::from)?;
        let element_bytes = match content {
            Content::Npy(element) => element.size(),
            Content::Image { .. } | Content::Babylon { .. } => 4,
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
            texture.write(&npy_header(element.descr(), &shape))?;
        }
        Ok(texture)
    }

    /// The file's name (as the sidecar lists it).
    pub(super) fn name(&self) -> String {
        self.file.path().file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
    }

    /// Appends `values` (whole rows): written and hashed on another core, or gathered.
    pub(super) fn append(&mut self, values: &[f32]) -> Result<(), InputError> {
        self.left = (self.left.checked_sub(values.len() as u64))
            .ok_or_else(|| InternalError::Overfull(self.file.path().to_path_buf()))?;
        match &mut self.content {
            Content::Npy(element) => {
                let bytes = element.bytes(values);
                self.write(&bytes)
            }
            Content::Image { rows, .. } | Content::Babylon { rows, .. } => {
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
        written.map_err(|e| OutputError::from(self.file.error(e)))?;
        self.size += bytes.len() as u64;
        Ok(())
    }

    /// Commits the file once its shape is filled (an image encoded first); what the manifest
    /// and the sidecar record of it.
    pub(super) fn finish(mut self) -> Result<Written, InputError> {
        let path = self.file.path().to_path_buf();
        if self.left != 0 {
            return Err(InternalError::Short { file: path, left: self.left }.into());
        }
        let image = match std::mem::replace(&mut self.content, Content::Npy(NpyElement::F32)) {
            Content::Npy(_) => None,
            Content::Babylon { from_world, bones, rows } => {
                self.write(&babylon::json(&babylon::matrices(&rows, bones, &from_world), bones))?;
                None
            }
            Content::Image { format, texels: what, half, grid, joints, rows } => {
                let internal =
                    |e: ImageError| InternalError::Encode { what: path.display().to_string(), error: e.into() };
                let (texels, bounds) = image::encode(what, &grid, joints, &rows).map_err(internal)?;
                let (bytes, remap) = match format {
                    Format::Exr => (image::exr(&grid, &texels, half).map_err(internal)?, None),
                    #[cfg(feature = "plot")]
                    Format::Png16 => match what {
                        Texels::Rows(kind) => {
                            let remap = image::ranges(kind, &rows);
                            (image::png16(&grid, &texels, &remap).map_err(internal)?, Some(remap))
                        }
                        // Encoded in 0..1 already.
                        Texels::Positions | Texels::Normals => {
                            (image::png16(&grid, &texels, &[[[0.0, 1.0]; 4]]).map_err(internal)?, None)
                        }
                    },
                    _ => return Err(OutputError::NotBuilt { what: "PNG textures", feature: "plot" }.into()),
                };
                self.write(&bytes)?;
                Some(ImageTexture { grid, joints, remap, bounds })
            }
        };
        self.file.commit().map_err(OutputError::from)?;
        Ok(Written { path, hash: Some((self.size, super::manifest::hex(&self.hasher.finalize()))), image })
    }
}

/// Finishes every texture ([`TextureFile::finish`]) on every core (an image's encoding is
/// single-threaded, and an input may have a hundred images) and records each file
/// committed in `written`, so a failure leaves none of them unlisted; the first error.
pub(super) fn finish_all(textures: Vec<TextureFile>, written: &mut Vec<Written>) -> Result<(), InputError> {
    use rayon::prelude::*;
    let results: Vec<Result<Written, InputError>> = textures.into_par_iter().map(TextureFile::finish).collect();
    let mut first = Ok(());
    for result in results {
        match result {
            Ok(file) => written.push(file),
            Err(e) if first.is_ok() => first = Err(e),
            Err(_) => {}
        }
    }
    first
}

/// One [`TextureFile`] per sheet, each of `rows` rows, at `path(suffix)`; `what` names the
/// texture in messages.
pub(super) fn open(
    sheets: &[SheetSpec],
    options: &TextureOptions,
    rows: usize,
    what: &str,
    path: impl Fn(&str) -> PathBuf,
) -> Result<Vec<TextureFile>, BakeError> {
    if options.format != Format::Npy {
        let gathered = |sheet: &SheetSpec| (rows * sheet.width * sheet.texels.channels() * 4) as u64;
        let total: u64 = sheets.iter().map(gathered).sum();
        if total > IMAGE_MEMORY_LIMIT {
            let largest = sheets.iter().max_by_key(|s| gathered(s)).map_or("", |s| s.label.as_str());
            return Err(Refusal::ImagesMemory {
                texture: what.into(),
                images: sheets.len(),
                format: options.format.name(),
                mib: total.div_ceil(1 << 20),
                largest: largest.into(),
                largest_mib: sheets.iter().map(gathered).max().unwrap_or(0).div_ceil(1 << 20),
                limit: IMAGE_MEMORY_LIMIT,
            }
            .into());
        }
    }
    sheets.iter().map(|sheet| TextureFile::create(path(&sheet.suffix), options, sheet, rows, what)).collect()
}

/// Computes a clip's sheets a block of its `frames` at a time (`rows` of the frames asked
/// for, one sheet per texture) and appends each block to `textures` on another thread as the
/// next block is computed: the texture is never whole in memory, and the disk writes overlap
/// the arithmetic.
pub(super) fn stream(
    frames: usize,
    mut rows: impl FnMut(&[usize]) -> Result<Vec<texture::Sheet>, BakeError>,
    textures: &mut [TextureFile],
) -> Result<(), BakeError> {
    let row_bytes = textures.iter().map(|t| t.row_bytes).sum::<usize>().max(1);
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
            match rows(&picks) {
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
        let written = writer.join().unwrap_or_else(|_| Err(InternalError::Panicked("texture writer").into()));
        computed.and(written.map_err(BakeError::from))
    })
}
