//! What a renderer binds to play a bake with the shipped shaders (`quatcurve shaders`), so it
//! needs neither the viewer nor hand-packing: per image texture the shader's layout uniform
//! (`bone_layout` or `vertex_layout`) as named fields and as std140 bytes, and per bake the
//! vertex shader's inputs and resources with the names naga's GLSL gave them. Every number
//! comes from the WGSL (quatcurve-shader's reflection): member names, offsets, array limits,
//! locations.

use super::image::Grid;
use super::texture::TextureKind;
use crate::error::LayoutError;
use base64::Engine as _;
use quatcurve_shader::{self as shader, Language, Program};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

/// One texture's layout uniform, ready to bind.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct UniformRecord {
    /// The WGSL uniform it fills and that uniform's struct (`bone_layout`: `BoneLayout`,
    /// `vertex_layout`: `VertexLayout`).
    pub variable: String,
    /// See [`Self::variable`].
    #[serde(rename = "struct")]
    pub struct_name: String,
    /// The sidecar's clips the layout holds, by index: an instance plays `clips[k]` with
    /// `instance_clip = k` (for an atlas every clip of the file, up to the shader's limit;
    /// else the file's one clip, at 0).
    pub clips: Vec<usize>,
    /// The struct's members by name, every one, as the shader holds them (`f32` values, arrays
    /// at their full length, unused clips zero): for renderers that set uniforms by name.
    pub fields: Value,
    /// The struct's bytes (std140, which is also WGSL's uniform layout here), base64: a
    /// uniform buffer's contents as they are.
    pub std140: String,
}

/// A clip's entry in a layout's `clips` array (WGSL `BoneClip`).
pub(super) struct LayoutClip {
    pub(super) index: usize,
    pub(super) first_row: usize,
    pub(super) frames: usize,
    pub(super) looping: bool,
    pub(super) rate: f64,
}

/// What a texture's layout is made of besides its grid and clips.
pub(super) enum LayoutOf<'a> {
    /// A bone texture: per texel slot and channel, PNG16's `[min, max]` (none: EXR, 0 and 1).
    Bones { remap: Option<&'a [[[f32; 2]; 4]]> },
    /// A vertex texture's `.pos` file: its box, and whether a `.nrm` file goes with it.
    Vertex { low: [f64; 3], span: [f64; 3], normals: bool },
}

impl LayoutOf<'_> {
    fn program(&self) -> Program {
        match self {
            LayoutOf::Bones { .. } => Program::Bones,
            LayoutOf::Vertex { .. } => Program::Vertex,
        }
    }
}

/// The shipped program whose layout uniform a bake's images take (the vertex program's for
/// vertex textures, the bone program's else), parsed once for all of them.
pub(super) struct Layouts {
    program: Program,
    module: naga::Module,
}

impl Layouts {
    /// The layouts of a `texture` bake's images.
    ///
    /// # Errors
    /// naga's (a bug: the tests parse every program).
    pub(super) fn new(texture: TextureKind) -> Result<Self, LayoutError> {
        let program = if texture == TextureKind::Vertex { Program::Vertex } else { Program::Bones };
        Ok(Self { program, module: shader::parse(program.files())?.0 })
    }

    /// The layout uniform of a texture on `grid` holding `clips` (in the sidecar's order).
    ///
    /// # Errors
    /// A number the shader's struct cannot hold, named (a bug where the shader and this
    /// disagree on a member's name); a layout of the other program.
    pub(super) fn layout(
        &self,
        grid: &Grid,
        of: &LayoutOf<'_>,
        clips: &[LayoutClip],
    ) -> Result<UniformRecord, LayoutError> {
        if of.program() != self.program {
            return Err(LayoutError::Program { layout: of.program(), program: self.program });
        }
        layout(&self.module, grid, of, clips)
    }
}

fn layout(
    module: &naga::Module,
    grid: &Grid,
    of: &LayoutOf<'_>,
    clips: &[LayoutClip],
) -> Result<UniformRecord, LayoutError> {
    let (variable, struct_name, limit) = match of {
        LayoutOf::Bones { .. } => ("bone_layout", "BoneLayout", "BONE_MAX_CLIPS"),
        LayoutOf::Vertex { .. } => ("vertex_layout", "VertexLayout", "VERTEX_MAX_CLIPS"),
    };
    let limit = shader::constant_u32(module, limit).ok_or(LayoutError::NoConstant { name: limit })?;
    let clips = &clips[..clips.len().min(limit as usize)];
    let clip_fields: Vec<Value> = clips
        .iter()
        .map(|c| json!({"first_row": c.first_row, "frames": c.frames, "looping": c.looping, "rate": c.rate}))
        .collect();
    let mut fields = json!({
        "frame_width": grid.frame_width,
        "rows_per_frame": grid.rows_per_frame,
        "frames_per_column": grid.frames_per_column,
        "clips": clip_fields,
    });
    let extra = match of {
        LayoutOf::Bones { remap } => {
            let slots = |pick: fn([f32; 2]) -> f32| -> Vec<[f32; 4]> {
                match remap {
                    Some(remap) => remap.iter().map(|slot| slot.map(pick)).collect(),
                    None => vec![[pick([0.0, 1.0]); 4]; grid.texels_per_joint],
                }
            };
            json!({
                "texels_per_joint": grid.texels_per_joint,
                "low": slots(|[low, _]| low),
                // The span computed in f64 and rounded to f32 once.
                "span": slots(|[low, high]| (f64::from(high) - f64::from(low)) as f32),
            })
        }
        LayoutOf::Vertex { low, span, normals } => json!({
            "has_normals": normals,
            "low": [low[0], low[1], low[2], 0.0],
            "span": [span[0], span[1], span[2], 0.0],
        }),
    };
    if let (Some(fields), Some(extra)) = (fields.as_object_mut(), extra.as_object()) {
        fields.extend(extra.clone());
    }
    let bytes = shader::uniform::bytes(module, struct_name, &fields)?;
    Ok(UniformRecord {
        variable: variable.to_string(),
        struct_name: struct_name.to_string(),
        clips: clips.iter().map(|c| c.index).collect(),
        fields: shader::uniform::fields(module, struct_name, &bytes)?,
        std140: base64::engine::general_purpose::STANDARD.encode(bytes),
    })
}

/// The shipped vertex shader that plays a bake and what a renderer binds to it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShaderRecord {
    /// `quatcurve shaders --program` (`bones` for `skin-trs`, `vertex` for vertex textures).
    pub program: String,
    /// Its vertex entry point.
    pub entry_point: String,
    /// Its vertex inputs, by location.
    pub inputs: Vec<ShaderInput>,
    /// Its textures and uniform blocks.
    pub resources: Vec<ShaderResource>,
}

/// A vertex input of the shipped vertex shader.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShaderInput {
    /// The WGSL name.
    pub name: String,
    /// Its `@location`.
    pub location: u32,
    /// Where its values come from: a glTF attribute of the mesh (`POSITION`, `NORMAL`,
    /// `JOINTS_0`, `WEIGHTS_0`, `TEXCOORD_0`) or `instance` (one value per instance).
    pub from: String,
    /// The name naga's GLSL gives it (GLSL ES and 4.50 alike).
    pub glsl: String,
}

/// A texture or uniform block of the shipped vertex shader.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShaderResource {
    /// The WGSL variable, its `@group` and `@binding`.
    pub name: String,
    /// See [`Self::name`].
    pub group: u32,
    /// See [`Self::name`].
    pub binding: u32,
    /// `texture` or `uniform`.
    pub kind: String,
    /// The GLSL sampler, or the uniform block's name, naga gave it.
    pub glsl: String,
}

/// Where each of the shipped vertex shaders' inputs comes from.
fn input_source(name: &str) -> Option<&'static str> {
    Some(match name {
        "position" => "POSITION",
        "normal" => "NORMAL",
        "joints" => "JOINTS_0",
        "weights" => "WEIGHTS_0",
        "uv" | "address" => "TEXCOORD_0",
        "instance_offset" | "instance_clip" | "instance_time" => "instance",
        _ => return None,
    })
}

/// The record of `program`'s vertex shader.
///
/// # Errors
/// naga's, or an input this file does not know the source of (a bug: the tests bake both).
pub(super) fn shader_record(program: Program) -> Result<ShaderRecord, LayoutError> {
    let entry = program.entry_point();
    let glsl = shader::glsl(program.files(), entry, program.stage(), Language::GlslEs)?;
    let (module, _) = shader::parse(program.files())?;
    let inputs = shader::vertex_inputs(&module, entry)?
        .into_iter()
        .map(|(name, location)| {
            let from = input_source(&name).ok_or_else(|| LayoutError::InputSource { name: name.clone() })?;
            let glsl = glsl.vertex_input(location).ok_or(LayoutError::NoGlslInput { location })?;
            Ok(ShaderInput { from: from.to_string(), glsl, name, location })
        })
        .collect::<Result<Vec<_>, LayoutError>>()?;
    let mut resources: Vec<ShaderResource> = glsl
        .bindings
        .into_iter()
        .map(|b| ShaderResource {
            name: b.wgsl,
            group: b.group,
            binding: b.binding,
            kind: if b.sampler { "texture" } else { "uniform" }.to_string(),
            glsl: b.glsl,
        })
        .collect();
    resources.sort_by_key(|r| (r.group, r.binding));
    Ok(ShaderRecord { program: program.to_string(), entry_point: entry.to_string(), inputs, resources })
}
