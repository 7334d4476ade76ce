//! A baked image as the texels a GPU samples from it: EXR's floats (half widened exactly),
//! PNG16's unsigned-normalized values (`v / 65535`, as an `rgba16unorm` texture reads). A
//! browser decodes neither format to these values (no EXR; PNG to 8 bits), so the viewer's
//! server sends them as raw little-endian `f32` RGBA, row 0 first.

use crate::error::ViewError;
use std::path::Path;

/// An RGBA image of `f32` texels, row-major from row 0 (the texture's `y = 0`).
pub struct Texels {
    /// Texels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width * height` texels.
    pub rgba: Vec<[f32; 4]>,
}

impl Texels {
    /// The texels of the `.exr` or `.png` file at `path`.
    ///
    /// # Errors
    /// The decoder's message, or a PNG that is not 16-bit RGBA (what `--format png16` writes).
    pub fn read(path: &Path) -> Result<Self, ViewError> {
        if path.extension().is_some_and(|e| e == "exr") {
            let image = exr::prelude::read_first_rgba_layer_from_file(
                path,
                |size, _| (size.width(), vec![[0.0f32; 4]; size.width() * size.height()]),
                |(width, texels), at, (r, g, b, a): (f32, f32, f32, f32)| {
                    texels[at.y() * *width + at.x()] = [r, g, b, a]
                },
            )?;
            let (width, rgba) = image.layer_data.channel_data.pixels;
            let height = rgba.len().checked_div(width).unwrap_or(0);
            Ok(Self { width, height, rgba })
        } else {
            match image::open(path)? {
                image::DynamicImage::ImageRgba16(buffer) => Ok(Self {
                    width: buffer.width() as usize,
                    height: buffer.height() as usize,
                    rgba: buffer.pixels().map(|p| p.0.map(|v| f32::from(v) / 65535.0)).collect(),
                }),
                other => Err(ViewError::PngColor { color: format!("{:?}", other.color()) }),
            }
        }
    }

    /// Texel `(x, y)`.
    #[must_use]
    pub fn at(&self, (x, y): (usize, usize)) -> [f32; 4] {
        self.rgba[y * self.width + x]
    }

    /// The texels as little-endian bytes, `f32` RGBA.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        self.rgba.iter().flatten().flat_map(|v| v.to_le_bytes()).collect()
    }
}
