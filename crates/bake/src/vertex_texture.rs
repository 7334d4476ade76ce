//! Vertex textures (DESIGN section 8): every skinned primitive of a glTF skinned at each
//! frame on the bake's device, as the sheets a texture file streams. As `.npy`, one sheet
//! per primitive of raw positions and normals (`[frames, vertices, 6]`); as images, a
//! position sheet and (when the primitive has normals) a normal sheet, which the image
//! encodes once its rows are complete (the positions' box is known only then).

use super::image::Texels;
use super::texture::{self, Sheet, TextureKind, VERTEX_CHANNELS};
use super::texture_file::SheetSpec;
use super::Baked;
use crate::error::BakeError;
use quatcurve_anim::Animation;
use quatcurve_device::Device;
use quatcurve_formats::mesh::SkinnedPrimitive;
use std::sync::Mutex;
use std::time::Instant;

/// The file-name suffix of primitive `k`'s sheets (`.mesh<k>`, then `.pos` or `.nrm` for
/// images).
#[must_use]
pub fn suffix(k: usize) -> String {
    format!(".mesh{k}")
}

/// The skinned primitives of one input and how their sheets are laid out; counts the
/// skinning work done, for the bake's report.
pub struct VertexSheets {
    /// The primitives, in [`quatcurve_formats::mesh::skinned_primitives`] order.
    pub primitives: Vec<SkinnedPrimitive>,
    /// Position and normal images (EXR, PNG16) rather than raw `.npy` rows.
    images: bool,
    /// Vertex-frames skinned and seconds spent skinning them.
    work: Mutex<(u64, f64)>,
}

impl VertexSheets {
    /// The sheets of `primitives`, as images or as `.npy` rows.
    #[must_use]
    pub fn new(primitives: Vec<SkinnedPrimitive>, images: bool) -> Self {
        Self { primitives, images, work: Mutex::new((0, 0.0)) }
    }

    /// The files of each clip's (or the atlas's) texture, in the order [`Self::rows`] makes
    /// their sheets.
    pub(super) fn layout(&self) -> Vec<SheetSpec> {
        let mut out = Vec::new();
        for (k, p) in self.primitives.iter().enumerate() {
            let width = p.vertices();
            let sheet = |suffix: String, what: &str, texels: Texels| SheetSpec {
                suffix,
                label: format!("{}'s {what}", p.name),
                width,
                texels,
                babylon: None,
            };
            if !self.images {
                out.push(sheet(suffix(k), "vertices", Texels::Rows(TextureKind::Vertex)));
                continue;
            }
            out.push(sheet(format!("{}.pos", suffix(k)), "positions", Texels::Positions));
            if p.bind.normals.is_some() {
                out.push(sheet(format!("{}.nrm", suffix(k)), "normals", Texels::Normals));
            }
        }
        out
    }

    /// The sheets of [`Self::layout`] for clip `clip`'s `frames`: the skins' matrices
    /// ([`texture::sheet_rows`], forward kinematics on `device`), then every primitive skinned
    /// on `device` ([`Device::skin`]).
    ///
    /// # Errors
    /// The GPU's.
    pub fn rows(
        &self,
        animation: &Animation,
        order: &[usize],
        baked: &Baked,
        clip: usize,
        device: &Device,
        frames: &[usize],
    ) -> Result<Vec<Sheet>, BakeError> {
        let skins = texture::sheet_rows(animation, order, baked, clip, TextureKind::Skin, device, frames)?;
        let mut out = Vec::new();
        for (k, p) in self.primitives.iter().enumerate() {
            let joints = animation.skins[p.skin].joints.len();
            let start = Instant::now();
            let data = device
                .skin(&p.bind, joints, &skins[p.skin].data)
                .map_err(|error| BakeError::Skinning { primitive: p.name.clone(), error: Box::new(error) })?;
            {
                let mut work = self.work.lock().unwrap_or_else(|e| e.into_inner());
                work.0 += (frames.len() * p.vertices()) as u64;
                work.1 += start.elapsed().as_secs_f64();
            }
            let width = p.vertices();
            if !self.images {
                out.push(Sheet { suffix: suffix(k), width, data, shear: 0.0 });
                continue;
            }
            let part = |range: std::ops::Range<usize>| -> Vec<f32> {
                data.chunks_exact(VERTEX_CHANNELS).flat_map(|v| v[range.clone()].iter().copied()).collect()
            };
            out.push(Sheet { suffix: format!("{}.pos", suffix(k)), width, data: part(0..3), shear: 0.0 });
            if p.bind.normals.is_some() {
                out.push(Sheet { suffix: format!("{}.nrm", suffix(k)), width, data: part(3..6), shear: 0.0 });
            }
        }
        Ok(out)
    }

    /// Vertex-frames skinned so far and the seconds spent on them (skinning alone, without
    /// forward kinematics or writing).
    #[must_use]
    pub fn work(&self) -> (u64, f64) {
        *self.work.lock().unwrap_or_else(|e| e.into_inner())
    }
}
