//! Animation textures as images an engine imports (DESIGN section 6, `--format`): a 2D RGBA
//! texture with each joint's floats in a fixed number of texels, frames along rows, wrapped so
//! that neither side exceeds the largest texture size asked for ([`Grid`]), written as
//! OpenEXR (half or float) or 16-bit PNG (each channel remapped to its own range, recorded
//! in the sidecar as OpenVAT does). A vertex texture's images hold positions in their box
//! and octahedral normals instead (DESIGN section 8), both in `0..1`.
use super::texture::TextureKind;
use super::vertex_encoding::{encode_normal, Bounds};
use crate::error::GridError;
use serde::Serialize;

/// What an image's texels hold, made from the rows its file gathered ([`encode`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Texels {
    /// A texture's floats as they are: [`TextureKind::texels`] texels of each joint's.
    Rows(TextureKind),
    /// Skinned positions (three floats a vertex), remapped into their box: `(x, y, z, 1)`.
    Positions,
    /// Skinned unit normals (three floats a vertex), octahedral: `(u, v, 0, 1)`.
    Normals,
}

impl Texels {
    /// Floats per joint or vertex in the rows gathered.
    #[must_use]
    pub fn channels(self) -> usize {
        match self {
            Texels::Rows(kind) => kind.channels(),
            Texels::Positions | Texels::Normals => 3,
        }
    }
}

/// How a bake writes its textures (`bake --format`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// numpy `.npy` arrays `[frames, joints, channels]`, little-endian f32 or f16.
    #[default]
    Npy,
    /// OpenEXR RGBA, float or (`--precision f16`) half, ZIP-compressed scan lines.
    Exr,
    /// 16-bit PNG RGBA, each channel of each texel slot remapped from its own `[min, max]`.
    Png16,
    /// Babylon.js's baked vertex animation JSON, of `skin` textures ([`crate::babylon`]).
    Babylon,
}

quatcurve_core::curve::names!(Format, "format", Npy => "npy", Exr => "exr", Png16 => "png16", Babylon => "babylon");

impl Format {
    /// The file-name extension.
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Format::Npy => "npy",
            Format::Exr => "exr",
            Format::Png16 => "png",
            Format::Babylon => "json",
        }
    }

    /// An image engines import (EXR, PNG16), laid out on a [`Grid`] and recorded in the
    /// sidecar's `textures`.
    #[must_use]
    pub fn is_image(self) -> bool {
        matches!(self, Format::Exr | Format::Png16)
    }
}

/// The largest texture side written by default (`--max-texture-size`): what every desktop and
/// mobile GPU of the last decade samples (WebGL2 guarantees 2048, most offer 4096 or more).
pub const DEFAULT_MAX_TEXTURE_SIZE: usize = 4096;

/// Largest value of a 16-bit channel.
#[cfg(feature = "plot")]
const PNG16_MAX: f64 = 65535.0;

/// Where each joint's texels sit in a 2D texture of `frames` frames: a frame's texels are
/// joint after joint, `texels_per_joint` each, in rows of `frame_width` texels (a whole number
/// of joints), `rows_per_frame` rows per frame; frames go down a column of `frames_per_column`
/// frames, and columns side by side when one would be taller than the largest side. Texel `t`
/// of joint `j` in row `r` (frame `f` of a clip that starts at row `first_row` of the file, so
/// `r = first_row + f`), with `a = j * texels_per_joint + t`, is at
/// `x = (r / frames_per_column) * frame_width + a % frame_width`,
/// `y = (r % frames_per_column) * rows_per_frame + a / frame_width` ([`Grid::texel`], and
/// [`ADDRESS`] in words).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct Grid {
    /// Texels per row of the image.
    pub width: usize,
    /// Rows of the image.
    pub height: usize,
    /// Texels each joint takes ([`TextureKind::texels`]).
    pub texels_per_joint: usize,
    /// Texels per row of one frame (a column's width).
    pub frame_width: usize,
    /// Image rows each frame takes (1 unless a frame's joints are wider than the largest side).
    pub rows_per_frame: usize,
    /// Frames down one column before the next column starts.
    pub frames_per_column: usize,
}

/// [`Grid::texel`]'s formula as the sidecar states it (`address`), with each file's numbers
/// beside it.
pub const ADDRESS: &str = "a = j * texels_per_joint + t, r = first_row + frame, \
    x = (r / frames_per_column) * frame_width + a % frame_width, \
    y = (r % frames_per_column) * rows_per_frame + a / frame_width (integer division)";

/// Why a texture could not be laid out or encoded as an image.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImageError {
    /// The frames do not fit an image of the largest side.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// A skinned position that is not finite, which no box holds.
    #[error("a skinned position is not finite")]
    NotFinite,
    /// The EXR encoder failed.
    #[error(transparent)]
    Exr(#[from] exr::error::Error),
    /// The PNG encoder failed.
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Png(#[from] image::ImageError),
    /// Texels that do not fill the image (a bug).
    #[error("the texels do not fill the image")]
    Unfilled,
}

impl Grid {
    /// The grid of `frames` frames of `joints` joints of `kind` within `max` texels a side.
    ///
    /// # Errors
    /// The reason in words, naming the limit, when the frames cannot fit.
    pub fn new(kind: TextureKind, joints: usize, frames: usize, max: usize) -> Result<Self, GridError> {
        let texels_per_joint = kind.texels().len();
        let per_frame = (joints * texels_per_joint).max(1);
        let frame_width = per_frame.min(max / texels_per_joint * texels_per_joint);
        if frame_width == 0 {
            return Err(GridError::JointTooWide { texels_per_joint, max });
        }
        let rows_per_frame = per_frame.div_ceil(frame_width);
        let most_per_column = max / rows_per_frame;
        let columns = frames.max(1).div_ceil(most_per_column.max(1));
        if most_per_column == 0 || columns * frame_width > max {
            return Err(GridError::FramesDoNotFit {
                frames,
                joints,
                texels: frames * per_frame,
                rows_per_frame,
                frame_width,
                max,
            });
        }
        // Columns of even height, so the image wastes less than a frame per column.
        let frames_per_column = frames.max(1).div_ceil(columns);
        Ok(Self {
            width: columns * frame_width,
            height: frames_per_column * rows_per_frame,
            texels_per_joint,
            frame_width,
            rows_per_frame,
            frames_per_column,
        })
    }

    /// `(x, y)` of texel `texel` of joint `joint` in row `row` (a frame of the file).
    #[must_use]
    pub fn texel(&self, row: usize, joint: usize, texel: usize) -> (usize, usize) {
        let at = joint * self.texels_per_joint + texel;
        let (column, down) = (row / self.frames_per_column, row % self.frames_per_column);
        (column * self.frame_width + at % self.frame_width, down * self.rows_per_frame + at / self.frame_width)
    }
}

/// The image of `rows` (frame-major rows of `joints` joints or vertices, [`Texels::channels`]
/// floats each) on `grid`, with the box positions were remapped into.
///
/// # Errors
/// A position that is not finite, in words.
pub fn encode(
    what: Texels,
    grid: &Grid,
    joints: usize,
    rows: &[f32],
) -> Result<(Vec<[f32; 4]>, Option<Bounds>), ImageError> {
    let bounds = match what {
        Texels::Rows(kind) => return Ok((texels(kind, grid, joints, rows), None)),
        Texels::Positions => {
            let positions = rows.chunks_exact(3).map(|p| [p[0], p[1], p[2]].map(f64::from));
            Some(Bounds::of_positions(positions).ok_or(ImageError::NotFinite)?)
        }
        Texels::Normals => None,
    };
    let encoded = |value: &[f32]| -> [f32; 4] {
        let value = [value[0], value[1], value[2]].map(f64::from);
        match &bounds {
            Some(bounds) => {
                let [x, y, z] = bounds.encode(value);
                [x as f32, y as f32, z as f32, 1.0]
            }
            None => {
                let [u, v] = encode_normal(value);
                [u as f32, v as f32, 0.0, 1.0]
            }
        }
    };
    let mut image = vec![[0.0f32; 4]; grid.width * grid.height];
    for (row, values) in rows.chunks_exact(joints.max(1) * 3).enumerate() {
        for (v, value) in values.chunks_exact(3).enumerate() {
            let (x, y) = grid.texel(row, v, 0);
            image[y * grid.width + x] = encoded(value);
        }
    }
    Ok((image, bounds))
}

/// Texels of `rows` (frame-major rows of `joints` joints of `kind`'s channels) laid on `grid`,
/// `[x, y, z, w]` per texel, row after row of the image; texels no joint fills are zero.
#[must_use]
pub fn texels(kind: TextureKind, grid: &Grid, joints: usize, rows: &[f32]) -> Vec<[f32; 4]> {
    let channels = kind.channels();
    let mut image = vec![[0.0f32; 4]; grid.width * grid.height];
    for (row, values) in rows.chunks_exact(joints * channels).enumerate() {
        for joint in 0..joints {
            let floats = &values[joint * channels..(joint + 1) * channels];
            for (t, range) in kind.texels().iter().enumerate() {
                let (x, y) = grid.texel(row, joint, t);
                let texel = &mut image[y * grid.width + x];
                texel[..range.len()].copy_from_slice(&floats[range.clone()]);
            }
        }
    }
    image
}

/// Per texel slot and channel, the `[min, max]` of `rows`' values (frame-major rows of joints
/// of `kind`'s channels): what PNG16 maps to `0..=65535`; `[0, 0]` for a channel no float
/// fills.
#[must_use]
pub fn ranges(kind: TextureKind, rows: &[f32]) -> Vec<[[f32; 2]; 4]> {
    let slots = kind.texels();
    let mut out = vec![[[0.0f32; 2]; 4]; slots.len()];
    for (slot, range) in out.iter_mut().zip(slots) {
        for (c, pair) in range.clone().zip(slot.iter_mut()) {
            let values = rows.chunks_exact(kind.channels()).map(|floats| floats[c]);
            let (lo, hi) = values.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
            if lo <= hi {
                *pair = [lo, hi];
            }
        }
    }
    out
}

/// The OpenEXR bytes of `image` (`grid.width x grid.height` RGBA), half or float.
///
/// # Errors
/// The encoder's, in words.
pub fn exr(grid: &Grid, image: &[[f32; 4]], half: bool) -> Result<Vec<u8>, ImageError> {
    use exr::prelude::*;
    let size = (grid.width, grid.height);
    let at = |Vec2(x, y): Vec2<usize>| image[y * grid.width + x];
    let mut bytes = std::io::Cursor::new(Vec::new());
    let written = if half {
        let channels = SpecificChannels::rgba(|p| at(p).map(f16::from_f32).into());
        Image::from_encoded_channels(size, Encoding::SMALL_LOSSLESS, channels).write().to_buffered(&mut bytes)
    } else {
        let channels = SpecificChannels::rgba(|p| at(p).into());
        Image::from_encoded_channels(size, Encoding::SMALL_LOSSLESS, channels).write().to_buffered(&mut bytes)
    };
    written?;
    Ok(bytes.into_inner())
}

/// The 16-bit PNG bytes of `image`, each channel of texel slot `t` mapped from `ranges[t]` to
/// `0..=65535` (rounded to the nearest).
///
/// # Errors
/// The encoder's, in words.
#[cfg(feature = "plot")]
pub fn png16(grid: &Grid, image: &[[f32; 4]], ranges: &[[[f32; 2]; 4]]) -> Result<Vec<u8>, ImageError> {
    let mut samples = Vec::with_capacity(image.len() * 4);
    for (i, texel) in image.iter().enumerate() {
        let slot = &ranges[(i % grid.width) % grid.texels_per_joint];
        for (c, &v) in texel.iter().enumerate() {
            let [lo, hi] = slot[c].map(f64::from);
            let unit = if hi > lo { (f64::from(v) - lo) / (hi - lo) } else { 0.0 };
            samples.push((unit.clamp(0.0, 1.0) * PNG16_MAX).round() as u16);
        }
    }
    let buffer = image::ImageBuffer::<image::Rgba<u16>, _>::from_raw(grid.width as u32, grid.height as u32, samples)
        .ok_or(ImageError::Unfilled)?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    buffer.write_to(&mut bytes, image::ImageOutputFormat::Png)?;
    Ok(bytes.into_inner())
}
