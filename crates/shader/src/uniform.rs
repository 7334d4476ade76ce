//! A uniform struct of a WGSL program filled by name: a JSON object whose keys are the
//! struct's members becomes the bytes a host uploads, at the offsets naga reflects. So the
//! layout is written once, in the shader: the bake's sidecar carries both the named fields
//! (for engines that set uniforms by name, three.js) and these bytes (for a uniform buffer or
//! a GLSL std140 block), and the viewer binds the same bytes.

use naga::{ArraySize, Handle, Module, ScalarKind, Type, TypeInner, VectorSize};
use serde_json::Value;

/// Why a uniform struct could not be filled from named fields or read back: the struct, or the
/// member (by its path, such as `clips[3].rate`) and the rule it breaks.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum UniformError {
    /// The shader declares no such struct.
    #[error("the shader has no struct `{name}`")]
    NoStruct {
        /// The struct asked for.
        name: String,
    },
    /// Bytes of another size than the struct's.
    #[error("`{name}` is {size} bytes, not {given}")]
    Size {
        /// The struct.
        name: String,
        /// Its size in bytes.
        size: usize,
        /// The bytes given.
        given: usize,
    },
    /// A vector given another number of components.
    #[error("`{path}` has {given} components, not {expected}")]
    Components {
        /// The member.
        path: String,
        /// Components given.
        given: usize,
        /// The vector's.
        expected: usize,
    },
    /// An array given more elements than the shader's array holds.
    #[error("`{path}` has {given} elements; the shader holds {holds}")]
    Elements {
        /// The member.
        path: String,
        /// Elements given.
        given: usize,
        /// The array's length.
        holds: u32,
    },
    /// A struct not given as an object.
    #[error("`{path}` is not an object")]
    NotObject {
        /// The member.
        path: String,
    },
    /// A vector or array not given as an array.
    #[error("`{path}` is not an array")]
    NotArray {
        /// The member.
        path: String,
    },
    /// A field the struct does not have.
    #[error("`{path}` has no member `{member}`")]
    UnknownMember {
        /// The struct.
        path: String,
        /// The field given.
        member: String,
    },
    /// A member WGSL and std140 would place at different offsets.
    #[error("`{path}` is at byte {wgsl} in WGSL, {std140} in std140")]
    Std140 {
        /// The member.
        path: String,
        /// Its WGSL offset.
        wgsl: u32,
        /// Its std140 offset.
        std140: u32,
    },
    /// A member not given.
    #[error("`{path}` is missing")]
    Missing {
        /// The member.
        path: String,
    },
    /// A member of a type a uniform filled by name does not take.
    #[error("`{path}` is a {kind}, which a uniform filled by name does not take")]
    Unsupported {
        /// The member.
        path: String,
        /// Its type, as naga names it.
        kind: String,
    },
    /// A value its scalar cannot hold.
    #[error("`{path}` = {value} is not {expected}")]
    Value {
        /// The member.
        path: String,
        /// The value given.
        value: Value,
        /// What the scalar holds ("a u32").
        expected: &'static str,
    },
    /// A scalar of a kind a uniform filled by name does not take.
    #[error("`{path}` is a {kind} scalar")]
    Scalar {
        /// The member.
        path: String,
        /// Its kind, as naga names it.
        kind: String,
    },
    /// Bytes that end inside the member.
    #[error("`{path}` is cut short")]
    Short {
        /// The member.
        path: String,
    },
}

/// The bytes of struct `name` of `module` with its members taken from `fields` (an object
/// keyed by member name; nested structs as objects, vectors and arrays as arrays; an array
/// given fewer elements than its length is padded with zeros), little-endian. The layout is
/// WGSL's uniform layout, checked to be std140's too, so the bytes fill a GLSL uniform block
/// of the translated shader as they are.
///
/// # Errors
/// No such struct; a member missing, unknown or of the wrong kind (named by its path, such as
/// `clips[3].rate`); a number that its scalar cannot hold; a layout that std140 would place
/// differently.
pub fn bytes(module: &Module, name: &str, fields: &Value) -> Result<Vec<u8>, UniformError> {
    let ty = struct_type(module, name).ok_or_else(|| UniformError::NoStruct { name: name.into() })?;
    let mut out = vec![0; module.types[ty].inner.size(module.to_ctx()) as usize];
    Filler { module }.fill(ty, fields, 0, name, &mut out)?;
    Ok(out)
}

/// Struct `name` of `module` read back from its bytes as named fields, every member present
/// (arrays at their full length, scalars as the shader holds them: `f32`, `u32`, `i32`): the
/// complete value a renderer that sets uniforms by name assigns.
///
/// # Errors
/// No such struct; `bytes` not the struct's size; a member of a kind [`bytes`] does not take.
pub fn fields(module: &Module, name: &str, bytes: &[u8]) -> Result<Value, UniformError> {
    let ty = struct_type(module, name).ok_or_else(|| UniformError::NoStruct { name: name.into() })?;
    let size = module.types[ty].inner.size(module.to_ctx()) as usize;
    if bytes.len() != size {
        return Err(UniformError::Size { name: name.into(), size, given: bytes.len() });
    }
    Filler { module }.read(ty, bytes, 0, name)
}

/// The handle of struct `name`.
fn struct_type(module: &Module, name: &str) -> Option<Handle<Type>> {
    module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name) && matches!(t.inner, TypeInner::Struct { .. }))
        .map(|(h, _)| h)
}

struct Filler<'a> {
    module: &'a Module,
}

impl Filler<'_> {
    fn fill(&self, ty: Handle<Type>, value: &Value, at: u32, path: &str, out: &mut [u8]) -> Result<(), UniformError> {
        match &self.module.types[ty].inner {
            TypeInner::Scalar(scalar) => write_scalar(scalar.kind, value, at, path, out),
            TypeInner::Vector { size, scalar } => {
                let items = array_of(value, path)?;
                let n = vector_len(*size);
                if items.len() != n {
                    return Err(UniformError::Components { path: path.into(), given: items.len(), expected: n });
                }
                for (i, item) in items.iter().enumerate() {
                    write_scalar(scalar.kind, item, at + 4 * i as u32, &format!("{path}[{i}]"), out)?;
                }
                Ok(())
            }
            TypeInner::Array { base, size: ArraySize::Constant(len), stride } => {
                let items = array_of(value, path)?;
                if items.len() > len.get() as usize {
                    return Err(UniformError::Elements { path: path.into(), given: items.len(), holds: len.get() });
                }
                for (i, item) in items.iter().enumerate() {
                    self.fill(*base, item, at + i as u32 * stride, &format!("{path}[{i}]"), out)?;
                }
                Ok(())
            }
            TypeInner::Struct { members, .. } => {
                let object = value.as_object().ok_or_else(|| UniformError::NotObject { path: path.into() })?;
                if let Some(unknown) = object.keys().find(|k| !members.iter().any(|m| m.name.as_deref() == Some(k))) {
                    return Err(UniformError::UnknownMember { path: path.into(), member: unknown.clone() });
                }
                let mut std140 = 0u32;
                for m in members {
                    let member = m.name.as_deref().unwrap_or_default();
                    let inner = format!("{path}.{member}");
                    let (align, size) = self.std140(m.ty);
                    std140 = std140.next_multiple_of(align);
                    if std140 != m.offset {
                        return Err(UniformError::Std140 { path: inner, wgsl: m.offset, std140 });
                    }
                    std140 += size;
                    let given = object.get(member).ok_or_else(|| UniformError::Missing { path: inner.clone() })?;
                    self.fill(m.ty, given, at + m.offset, &inner, out)?;
                }
                Ok(())
            }
            other => Err(UniformError::Unsupported { path: path.into(), kind: format!("{other:?}") }),
        }
    }

    fn read(&self, ty: Handle<Type>, bytes: &[u8], at: u32, path: &str) -> Result<Value, UniformError> {
        Ok(match &self.module.types[ty].inner {
            TypeInner::Scalar(scalar) => read_scalar(scalar.kind, bytes, at, path)?,
            TypeInner::Vector { size, scalar } => Value::Array(
                (0..vector_len(*size) as u32)
                    .map(|i| read_scalar(scalar.kind, bytes, at + 4 * i, path))
                    .collect::<Result<_, _>>()?,
            ),
            TypeInner::Array { base, size: ArraySize::Constant(len), stride } => Value::Array(
                (0..len.get())
                    .map(|i| self.read(*base, bytes, at + i * stride, &format!("{path}[{i}]")))
                    .collect::<Result<_, _>>()?,
            ),
            TypeInner::Struct { members, .. } => {
                let mut object = serde_json::Map::new();
                for m in members {
                    let member = m.name.clone().unwrap_or_default();
                    let value = self.read(m.ty, bytes, at + m.offset, &format!("{path}.{member}"))?;
                    object.insert(member, value);
                }
                Value::Object(object)
            }
            other => return Err(UniformError::Unsupported { path: path.into(), kind: format!("{other:?}") }),
        })
    }

    /// std140's alignment and size of `ty` (GLSL 4.50 section 7.6.2.2): scalars 4, two
    /// components 8, three and four 16; arrays and structs aligned to 16, array elements
    /// rounded up to 16.
    fn std140(&self, ty: Handle<Type>) -> (u32, u32) {
        match &self.module.types[ty].inner {
            TypeInner::Vector { size: VectorSize::Bi, .. } => (8, 8),
            TypeInner::Vector { size, .. } => (16, 4 * vector_len(*size) as u32),
            TypeInner::Array { base, size: ArraySize::Constant(len), .. } => {
                let element = self.std140(*base).1.next_multiple_of(16);
                (16, element * len.get())
            }
            TypeInner::Struct { members, .. } => {
                let end = members.iter().fold(0u32, |at, m| {
                    let (align, size) = self.std140(m.ty);
                    at.next_multiple_of(align) + size
                });
                (16, end.next_multiple_of(16))
            }
            _ => (4, 4),
        }
    }
}

fn vector_len(size: VectorSize) -> usize {
    size as usize
}

fn array_of<'v>(value: &'v Value, path: &str) -> Result<&'v Vec<Value>, UniformError> {
    value.as_array().ok_or_else(|| UniformError::NotArray { path: path.into() })
}

fn write_scalar(kind: ScalarKind, value: &Value, at: u32, path: &str, out: &mut [u8]) -> Result<(), UniformError> {
    let word: [u8; 4] = match kind {
        ScalarKind::Uint | ScalarKind::Bool => match value {
            Value::Bool(b) => u32::from(*b),
            _ => value.as_u64().and_then(|v| u32::try_from(v).ok()).ok_or_else(|| UniformError::Value {
                path: path.into(),
                value: value.clone(),
                expected: "a u32",
            })?,
        }
        .to_le_bytes(),
        ScalarKind::Sint => value
            .as_i64()
            .and_then(|v| i32::try_from(v).ok())
            .ok_or_else(|| UniformError::Value { path: path.into(), value: value.clone(), expected: "an i32" })?
            .to_le_bytes(),
        ScalarKind::Float => {
            let v = value.as_f64().ok_or_else(|| UniformError::Value {
                path: path.into(),
                value: value.clone(),
                expected: "a number",
            })?;
            (v as f32).to_le_bytes()
        }
        other => return Err(UniformError::Scalar { path: path.into(), kind: format!("{other:?}") }),
    };
    out[at as usize..at as usize + 4].copy_from_slice(&word);
    Ok(())
}

fn read_scalar(kind: ScalarKind, bytes: &[u8], at: u32, path: &str) -> Result<Value, UniformError> {
    let word: [u8; 4] =
        bytes[at as usize..at as usize + 4].try_into().map_err(|_| UniformError::Short { path: path.into() })?;
    Ok(match kind {
        ScalarKind::Uint => Value::from(u32::from_le_bytes(word)),
        ScalarKind::Bool => Value::from(u32::from_le_bytes(word) != 0),
        ScalarKind::Sint => Value::from(i32::from_le_bytes(word)),
        ScalarKind::Float => Value::from(f64::from(f32::from_le_bytes(word))),
        other => return Err(UniformError::Scalar { path: path.into(), kind: format!("{other:?}") }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn module(src: &str) -> Module {
        naga::front::wgsl::parse_str(src).unwrap()
    }

    const LAYOUT: &str = "
        struct Clip { first: u32, rate: f32, n: i32, on: u32 }
        struct Layout { width: u32, low: array<vec4f, 2>, clips: array<Clip, 3> }
        @group(0) @binding(0) var<uniform> l: Layout;
    ";

    #[test]
    fn members_land_at_the_reflected_offsets_and_missing_elements_are_zero() {
        let given = json!({
            "width": 7,
            "low": [[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]],
            "clips": [{"first": 3, "rate": 30.0, "n": -2, "on": true}],
        });
        let out = bytes(&module(LAYOUT), "Layout", &given).unwrap();
        let word = |i: usize| u32::from_le_bytes(out[4 * i..4 * i + 4].try_into().unwrap());
        assert_eq!(out.len(), 16 + 32 + 48);
        assert_eq!(word(0), 7);
        assert_eq!([word(1), word(2), word(3)], [0, 0, 0], "padding to low's 16-byte alignment");
        assert_eq!(f32::from_bits(word(4)), 1.0);
        assert_eq!(f32::from_bits(word(11)), 8.0);
        assert_eq!((word(12), f32::from_bits(word(13)), word(14) as i32, word(15)), (3, 30.0, -2, 1));
        assert!(out[64..].iter().all(|&b| b == 0), "clips 1 and 2 not given: zero");
        let back = fields(&module(LAYOUT), "Layout", &out).unwrap();
        assert_eq!(back["clips"][0], json!({"first": 3, "rate": 30.0, "n": -2, "on": 1}));
        assert_eq!(
            back["clips"][2],
            json!({"first": 0, "rate": 0.0, "n": 0, "on": 0}),
            "every element, zero where not given"
        );
        assert_eq!(
            bytes(&module(LAYOUT), "Layout", &back).unwrap(),
            out,
            "the fields read back pack to the same bytes"
        );
    }

    #[test]
    fn a_wrong_member_is_named_by_its_path() {
        let m = module(LAYOUT);
        let clip = json!({"first": 1, "rate": 1.0, "n": 1, "on": 1});
        let with = |clips: Value| json!({"width": 1, "low": [], "clips": clips});
        let err = |v: Value| bytes(&m, "Layout", &v).unwrap_err().to_string();
        assert!(err(json!({"low": [], "clips": []})).contains("`Layout.width` is missing"));
        assert!(err(json!({"width": 1, "low": [], "clips": [], "extra": 0})).contains("no member `extra`"));
        assert!(err(with(json!([clip, {"first": -1, "rate": 1.0, "n": 1, "on": 1}])))
            .contains("`Layout.clips[1].first` = -1"));
        assert!(err(with(json!([clip, clip, clip, clip]))).contains("4 elements; the shader holds 3"));
        assert!(err(json!({"width": 1, "low": [[1.0, 2.0]], "clips": []})).contains("`Layout.low[0]` has 2 components"));
        assert_eq!(bytes(&m, "Nothing", &json!({})).unwrap_err(), UniformError::NoStruct { name: "Nothing".into() });
    }

    #[test]
    fn a_layout_std140_would_place_differently_is_refused() {
        // WGSL puts a vec2 array's elements 8 bytes apart in storage, but a uniform array's
        // stride must be 16; a struct member after a vec3 shows the rule that differs: std140
        // aligns a struct to 16, WGSL to its largest member (4 here).
        let m = module(
            "
            struct Inner { a: f32 }
            struct Outer { v: vec3f, inner: Inner }
            @group(0) @binding(0) var<storage> s: Outer;
        ",
        );
        let err = bytes(&m, "Outer", &json!({"v": [0.0, 0.0, 0.0], "inner": {"a": 1.0}})).unwrap_err();
        assert_eq!(err, UniformError::Std140 { path: "Outer.inner".into(), wgsl: 12, std140: 16 });
        assert_eq!(err.to_string(), "`Outer.inner` is at byte 12 in WGSL, 16 in std140");
    }
}
