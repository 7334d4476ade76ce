//! Draco-compressed mesh primitives (`KHR_draco_mesh_compression`), decoded by the pure-Rust
//! `draco-core`: the compressed bytes of a primitive's buffer view become a mesh whose
//! attributes the extension maps to glTF's (`POSITION`, `NORMAL`, `JOINTS_n`, ...) by their
//! Draco unique ids.

use draco_core::{DataType, DecoderBuffer, FaceIndex, Mesh, MeshDecoder, PointAttribute, PointIndex};

/// Why a Draco primitive could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DracoError {
    /// The decoder refused the bitstream.
    #[error(transparent)]
    Decode(#[from] draco_core::DracoError),
    /// No attribute of that unique id.
    #[error("no Draco attribute {0}")]
    NoAttribute(u32),
    /// An attribute with another component count.
    #[error("Draco attribute {id} has {has} components, not {expected}")]
    Components {
        /// The attribute's unique id.
        id: u32,
        /// Its components.
        has: u8,
        /// The components glTF's attribute has.
        expected: usize,
    },
    /// An attribute of a type glTF does not allow there.
    #[error("Draco attribute {id} holds {data_type}, which glTF does not allow here")]
    DataType {
        /// The attribute's unique id.
        id: u32,
        /// Its type, as the decoder names it.
        data_type: String,
    },
    /// A point whose value lies outside the decoded data.
    #[error("point {0}'s value lies outside the decoded data")]
    OutsideData(usize),
}

/// A decoded Draco primitive.
pub(super) struct Decoded {
    mesh: Mesh,
}

impl Decoded {
    /// Decodes a Draco mesh bitstream.
    ///
    /// # Errors
    /// [`DracoError::Decode`] with the decoder's error.
    pub(super) fn new(bytes: &[u8]) -> Result<Self, DracoError> {
        let mut mesh = Mesh::new();
        MeshDecoder::new().decode(&mut DecoderBuffer::new(bytes), &mut mesh)?;
        Ok(Self { mesh })
    }

    /// Points (glTF vertices).
    pub(super) fn points(&self) -> usize {
        self.mesh.num_points()
    }

    /// The triangles' vertex indices, three per face.
    pub(super) fn indices(&self) -> Vec<u32> {
        (0..self.mesh.num_faces()).flat_map(|f| self.mesh.face(FaceIndex(f as u32)).map(|p| p.0)).collect()
    }

    /// The attribute of Draco unique id `id`, `N` components per point, as f64: floats as they
    /// are, integers as their values or, when `normalized`, divided by their type's largest.
    ///
    /// # Errors
    /// No such attribute, another component count, a type glTF does not allow, a point whose
    /// value lies outside the decoded data.
    pub(super) fn attribute<const N: usize>(&self, id: u32, normalized: bool) -> Result<Vec<[f64; N]>, DracoError> {
        let attribute = self.mesh.attribute_by_unique_id(id).ok_or(DracoError::NoAttribute(id))?;
        if usize::from(attribute.num_components()) != N {
            return Err(DracoError::Components { id, has: attribute.num_components(), expected: N });
        }
        let (size, scale): (usize, f64) = match attribute.data_type() {
            DataType::Float32 => (4, 1.0),
            DataType::Uint8 => (1, if normalized { 255.0 } else { 1.0 }),
            DataType::Uint16 => (2, if normalized { 65535.0 } else { 1.0 }),
            other => return Err(DracoError::DataType { id, data_type: format!("{other:?}") }),
        };
        (0..self.points()).map(|p| value::<N>(attribute, p, size, scale)).collect()
    }
}

/// Point `p`'s value of `attribute`, `size`-byte components, integers divided by `scale`.
fn value<const N: usize>(
    attribute: &PointAttribute,
    p: usize,
    size: usize,
    scale: f64,
) -> Result<[f64; N], DracoError> {
    let index = attribute.mapped_index(PointIndex(p as u32)).0 as usize;
    let stride = usize::try_from(attribute.byte_stride()).unwrap_or(0);
    let mut bytes = [0u8; 16];
    let bytes = &mut bytes[..N * size];
    if !attribute.buffer().try_read(index * stride, bytes) {
        return Err(DracoError::OutsideData(p));
    }
    Ok(std::array::from_fn(|c| {
        let b = &bytes[c * size..(c + 1) * size];
        match size {
            4 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            2 => f64::from(u16::from_le_bytes([b[0], b[1]])) / scale,
            _ => f64::from(b[0]) / scale,
        }
    }))
}
