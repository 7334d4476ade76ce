//! The WGSL programs: composed from the crate's `shaders/*.wgsl` (the only place the GPU math lives, inside the
//! crate so that it packages alone),
//! validated by naga, translated to GLSL and HLSL by naga's back ends, and the source of the
//! layout facts a host needs (workgroup sizes, vertex inputs, uniform structs), so every
//! number a host shares with a shader is read from the shader. No wgpu: the bake reads its
//! uniform layouts here without a GPU.

pub mod uniform;

/// Why a program could not be composed, validated, translated or reflected. Every one is a bug
/// of this crate or of a shader edited by hand: the tests translate every program.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ShaderError {
    /// WGSL naga cannot parse or validate.
    #[error("{diagnostic}")]
    Wgsl {
        /// naga's diagnostic, rendered with the lines of source it points at.
        diagnostic: String,
    },
    /// naga's GLSL back end refused the module.
    #[error("GLSL: {0}")]
    Glsl(#[from] naga::back::glsl::Error),
    /// naga's HLSL back end refused the module.
    #[error("HLSL: {0}")]
    Hlsl(#[from] naga::back::hlsl::Error),
    /// A GLSL translation asked in another language.
    #[error("{language} is not GLSL")]
    NotGlsl {
        /// The language asked for.
        language: Language,
    },
    /// The module has no entry point of this name.
    #[error("no `{name}` entry point")]
    NoEntryPoint {
        /// The entry point asked for.
        name: String,
    },
    /// A compute entry point whose workgroup is not one-dimensional.
    #[error("workgroup size {size:?} is not one-dimensional")]
    WorkgroupSize {
        /// Its `@workgroup_size`.
        size: [u32; 3],
    },
    /// A uniform block of naga's GLSL that the library cannot turn into a uniform of its struct.
    #[error("uniform block `{block}`")]
    UniformBlock {
        /// The block as naga wrote it.
        block: String,
    },
    /// A resource's WGSL name that the GLSL already uses for something else.
    #[error("the GLSL already uses `{name}`")]
    NameTaken {
        /// The name.
        name: String,
    },
    /// A uniform struct that could not be filled or read.
    #[error(transparent)]
    Uniform(#[from] uniform::UniformError),
}

/// The shader files in the order they are concatenated into one module. WGSL has no
/// `#include`; module-scope declarations are order-independent, so order is only for reading.
pub const FILES: [(&str, &str); 5] = [
    ("real.wgsl", include_str!("../shaders/real.wgsl")),
    ("quat.wgsl", include_str!("../shaders/quat.wgsl")),
    ("basis.wgsl", include_str!("../shaders/basis.wgsl")),
    ("segment.wgsl", include_str!("../shaders/segment.wgsl")),
    ("eval.wgsl", include_str!("../shaders/eval.wgsl")),
];

/// The forward-kinematics program of bake's model textures: the quaternion helpers it shares
/// with the evaluator, then its kernel.
pub const FK_FILES: [(&str, &str); 3] = [
    ("real.wgsl", include_str!("../shaders/real.wgsl")),
    ("quat.wgsl", include_str!("../shaders/quat.wgsl")),
    ("fk.wgsl", include_str!("../shaders/fk.wgsl")),
];

/// Crowd playback's program: forward kinematics' files, then the pose blend and the skin
/// palettes around it (one module, so that one submission runs all three).
pub const PLAY_FILES: [(&str, &str); 4] =
    [FK_FILES[0], FK_FILES[1], FK_FILES[2], ("play.wgsl", include_str!("../shaders/play.wgsl"))];

/// Crowd playback from resident curves: the evaluator's files (its track records and curve
/// functions), forward kinematics and the playback program, then the per-instance pose
/// evaluation (`shaders/play_curves.wgsl`), one module for one submission.
pub const PLAY_CURVES_FILES: [(&str, &str); 8] = [
    FILES[0],
    FILES[1],
    FILES[2],
    FILES[3],
    FILES[4],
    FK_FILES[2],
    PLAY_FILES[3],
    ("play_curves.wgsl", include_str!("../shaders/play_curves.wgsl")),
];

/// The WebGPU viewer's vertex shader over playback's palettes: self-contained.
pub const PALETTE_VERTEX_FILES: [(&str, &str); 1] =
    [("palette_vertex.wgsl", include_str!("../shaders/palette_vertex.wgsl"))];

/// The mesh-skinning program of vertex textures: self-contained.
pub const SKIN_MESH_FILES: [(&str, &str); 1] = [("skin_mesh.wgsl", include_str!("../shaders/skin_mesh.wgsl"))];

/// The bone-texture library a renderer includes (`quatcurve shaders`): self-contained, read
/// with the bake's textures of `--format exr|png16` (DESIGN section 7).
pub const BONE_FILES: [(&str, &str); 1] = [("bone_texture.wgsl", include_str!("../shaders/bone_texture.wgsl"))];

/// The minimal skinned vertex shader over the bone library: what `quatcurve shaders` ships and
/// what the GLSL and HLSL are generated from.
pub const SKIN_VERTEX_FILES: [(&str, &str); 2] =
    [BONE_FILES[0], ("skin_vertex.wgsl", include_str!("../shaders/skin_vertex.wgsl"))];

/// The bone library's test and error probe: its functions at given (clip, joint, time) queries
/// in a compute pass, so the host measures the shader a renderer runs.
pub const BONE_PROBE_FILES: [(&str, &str); 2] =
    [BONE_FILES[0], ("bone_probe.wgsl", include_str!("../shaders/bone_probe.wgsl"))];

/// The vertex-texture library (composed after the bone library, whose frame rule it shares)
/// and its minimal crowd vertex shader: what `quatcurve shaders --program vertex` ships
/// (DESIGN section 8).
pub const VERTEX_TEXTURE_FILES: [(&str, &str); 3] = [
    BONE_FILES[0],
    ("vertex_texture.wgsl", include_str!("../shaders/vertex_texture.wgsl")),
    ("vertex_texture_vertex.wgsl", include_str!("../shaders/vertex_texture_vertex.wgsl")),
];

/// The vertex-texture library's test probe: its functions at given (clip, vertex, time)
/// queries in a compute pass.
pub const VERTEX_PROBE_FILES: [(&str, &str); 3] = [
    BONE_FILES[0],
    ("vertex_texture.wgsl", include_str!("../shaders/vertex_texture.wgsl")),
    ("vertex_probe.wgsl", include_str!("../shaders/vertex_probe.wgsl")),
];

/// The fragment shader of `quatcurve view`'s page: a fixed light on the crowd shaders' normal.
pub const VIEWER_FRAGMENT_FILES: [(&str, &str); 1] =
    [("viewer_fragment.wgsl", include_str!("../shaders/viewer_fragment.wgsl"))];

/// Name of the viewer's fragment entry point.
pub const VIEWER_FRAGMENT_ENTRY_POINT: &str = "viewer_fragment";

/// Name of the skinned vertex shader's entry point.
pub const SKIN_VERTEX_ENTRY_POINT: &str = "skin_vertex";

/// The WebGPU viewer's vertex shader over palettes (`shaders/palette_vertex.wgsl`).
pub const PALETTE_VERTEX_ENTRY_POINT: &str = "palette_vertex";

/// Name of the vertex-texture vertex shader's entry point.
pub const VERTEX_TEXTURE_ENTRY_POINT: &str = "vertex_texture_vertex";

/// Name of the vertex probe's entry point.
pub const VERTEX_PROBE_ENTRY_POINT: &str = "vertex_probe";

/// Name of the bone probe's entry point.
pub const BONE_PROBE_ENTRY_POINT: &str = "bone_probe";

/// Name of the mesh-skinning entry point.
pub const SKIN_MESH_ENTRY_POINT: &str = "skin_mesh";

/// Name of the forward-kinematics entry point.
pub const FK_ENTRY_POINT: &str = "forward_kinematics";

/// The playback program's pose blend (`shaders/play.wgsl`).
pub const PLAY_BLEND_ENTRY_POINT: &str = "play_blend";

/// The playback program's pose evaluation from resident curves (`shaders/play_curves.wgsl`).
pub const PLAY_CURVES_ENTRY_POINT: &str = "play_curves";

/// The playback program's skin palettes (`shaders/play.wgsl`).
pub const PLAY_PALETTE_ENTRY_POINT: &str = "play_palette";

/// Name of the compute entry point.
pub const ENTRY_POINT: &str = "evaluate";

/// Name of the write-only roofline entry point (same bindings and output bytes, no math).
pub const ROOFLINE_ENTRY_POINT: &str = "roofline";

/// The whole program as one WGSL source.
#[must_use]
pub fn source() -> String {
    join(&FILES)
}

/// The forward-kinematics program as one WGSL source.
#[must_use]
pub fn fk_source() -> String {
    join(&FK_FILES)
}

/// The playback program (blend, forward kinematics, palettes) as one WGSL source.
#[must_use]
pub fn play_source() -> String {
    join(&PLAY_FILES)
}

/// The playback program from resident curves as one WGSL source.
#[must_use]
pub fn play_curves_source() -> String {
    join(&PLAY_CURVES_FILES)
}

/// The WebGPU viewer's vertex shader as one WGSL source.
#[must_use]
pub fn palette_vertex_source() -> String {
    join(&PALETTE_VERTEX_FILES)
}

/// The viewer's fragment shader as one WGSL source.
#[must_use]
pub fn viewer_fragment_source() -> String {
    join(&VIEWER_FRAGMENT_FILES)
}

/// The mesh-skinning program as one WGSL source.
#[must_use]
pub fn skin_mesh_source() -> String {
    join(&SKIN_MESH_FILES)
}

/// The skinned vertex shader with the bone library, as one WGSL source.
#[must_use]
pub fn skin_vertex_source() -> String {
    join(&SKIN_VERTEX_FILES)
}

/// The bone probe with the bone library, as one WGSL source.
#[must_use]
pub fn bone_probe_source() -> String {
    join(&BONE_PROBE_FILES)
}

/// The vertex-texture library, its probe, as one WGSL source.
#[must_use]
pub fn vertex_probe_source() -> String {
    join(&VERTEX_PROBE_FILES)
}

/// What `quatcurve shaders` writes: a library and the minimal vertex shader over it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Program {
    /// Bone textures (`bone_texture.wgsl`) and a skinned vertex shader (`skin_vertex.wgsl`).
    #[default]
    Bones,
    /// Vertex textures (`vertex_texture.wgsl`, over the bone library's frame rule) and a
    /// vertex shader that reads them (`vertex_texture_vertex.wgsl`).
    Vertex,
    /// A fragment shader for either vertex shader (`viewer_fragment.wgsl`, the viewer's): a
    /// fixed light on the normal they pass at location 0.
    Fragment,
}

quatcurve_core::curve::names!(Program, "shader program", Bones => "bones", Vertex => "vertex", Fragment => "fragment");

impl Program {
    /// The WGSL files, in order.
    #[must_use]
    pub fn files(self) -> &'static [(&'static str, &'static str)] {
        match self {
            Program::Bones => &SKIN_VERTEX_FILES,
            Program::Vertex => &VERTEX_TEXTURE_FILES,
            Program::Fragment => &VIEWER_FRAGMENT_FILES,
        }
    }

    /// The entry point.
    #[must_use]
    pub fn entry_point(self) -> &'static str {
        match self {
            Program::Bones => SKIN_VERTEX_ENTRY_POINT,
            Program::Vertex => VERTEX_TEXTURE_ENTRY_POINT,
            Program::Fragment => VIEWER_FRAGMENT_ENTRY_POINT,
        }
    }

    /// The entry point's stage.
    #[must_use]
    pub fn stage(self) -> naga::ShaderStage {
        match self {
            Program::Bones | Program::Vertex => naga::ShaderStage::Vertex,
            Program::Fragment => naga::ShaderStage::Fragment,
        }
    }

    /// The whole program as one WGSL source.
    #[must_use]
    pub fn source(self) -> String {
        join(self.files())
    }
}

/// A shading language `quatcurve shaders` writes the bone library in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Language {
    /// WGSL, the source itself (WebGPU, wgpu).
    Wgsl,
    /// GLSL 4.50 core (OpenGL, Vulkan through glslang).
    Glsl,
    /// GLSL ES 3.00 (WebGL2, OpenGL ES 3).
    GlslEs,
    /// HLSL shader model 5.1 (Direct3D 12, Unity, Unreal).
    Hlsl,
}

quatcurve_core::curve::names!(Language, "shader language", Wgsl => "wgsl", Glsl => "glsl", GlslEs => "glsl-es", Hlsl => "hlsl");

impl Language {
    /// The usual file-name extension of a vertex shader in this language.
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Language::Wgsl => "wgsl",
            Language::Glsl | Language::GlslEs => "vert",
            Language::Hlsl => "hlsl",
        }
    }
}

/// `program` in `language`: the WGSL source as it is, or naga's GLSL or HLSL back end run on
/// it (generated, never kept as a second source).
///
/// # Errors
/// naga's, in words (a bug in this crate: the tests translate every language).
pub fn program_in(program: Program, language: Language) -> Result<String, ShaderError> {
    let source = program.source();
    let files: Vec<&str> = program.files().iter().map(|(name, _)| *name).collect();
    let generated = format!("// Generated by `quatcurve shaders` (naga) from shaders/{}.\n", files.join(", "));
    let mut out = String::new();
    match language {
        Language::Wgsl => return Ok(source),
        Language::Glsl | Language::GlslEs => {
            let glsl = glsl(program.files(), program.entry_point(), program.stage(), language)?;
            // GLSL has no bind groups: say which generated name each WGSL resource took, after
            // the `#version` line that must come first.
            let mut names: Vec<String> = glsl
                .bindings
                .iter()
                .map(|b| {
                    let kind = if b.sampler { "sampler2D" } else { "uniform block" };
                    format!("// {} (WGSL group {}, binding {}): {kind} {}\n", b.wgsl, b.group, b.binding, b.glsl)
                })
                .collect();
            names.sort();
            out = glsl.text;
            let split = out.find('\n').map_or(0, |i| i + 1);
            out.insert_str(split, &format!("{generated}{}", names.concat()));
        }
        Language::Hlsl => {
            use naga::back::hlsl;
            let (module, info) = validate(&source)?;
            let options = hlsl::Options::default();
            let pipeline = hlsl::PipelineOptions::default();
            out.push_str(&generated);
            hlsl::Writer::new(&mut out, &options, &pipeline).write(&module, &info, None).map_err(ShaderError::Hlsl)?;
        }
    }
    Ok(out)
}

/// `program`'s library in GLSL ES 3.00 without its entry point, for an engine that puts the
/// functions into shaders of its own (three.js's `onBeforeCompile`): naga's GLSL of the
/// program with the `#version` and precision lines, the entry point's inputs and outputs, its
/// `main` and the engine's camera (group 0) left out; each resource takes its WGSL name, and a
/// uniform block becomes a uniform of its struct (`uniform BoneLayout bone_layout;`), the same
/// member expressions, so an engine that sets uniforms by name fills it from the sidecar's
/// `layout.fields`.
///
/// # Errors
/// naga's, in words; a resource name that the GLSL already uses for something else.
pub fn library(program: Program) -> Result<String, ShaderError> {
    let glsl = glsl(program.files(), program.entry_point(), program.stage(), Language::GlslEs)?;
    let mut text = String::new();
    for line in glsl.text.lines() {
        if line.starts_with("void main()") {
            break;
        }
        let entry_io = ["layout(location", "in ", "out ", "smooth ", "flat "].iter().any(|p| line.starts_with(p));
        if line.starts_with("#version") || line.starts_with("precision ") || entry_io {
            continue;
        }
        text.push_str(line);
        text.push('\n');
    }
    let mut names = Vec::new();
    for b in &glsl.bindings {
        let block = format!("layout(std140) uniform {} {{ ", b.glsl);
        let start = text.find(&block);
        if b.group == 0 {
            // The engine's own camera: its declaration goes; nothing the library keeps reads it.
            if let Some(start) = start {
                let end = text[start..].find('\n').map_or(text.len(), |e| start + e + 1);
                text.replace_range(start..end, "");
            }
            continue;
        }
        let generated = match start {
            // `layout(std140) uniform Block { Struct _group_g_binding_b_vs; };`
            Some(start) => {
                let end = text[start..].find("};").map(|e| start + e + 2).ok_or_else(|| ShaderError::UniformBlock {
                    block: text[start..].lines().next().unwrap_or_default().to_string(),
                })?;
                let inner = text[start + block.len()..end - 2].trim().trim_end_matches(';').to_string();
                let (ty, name) =
                    inner.split_once(' ').ok_or_else(|| ShaderError::UniformBlock { block: inner.clone() })?;
                let declaration = format!("uniform {ty} {name};");
                text.replace_range(start..end, &declaration);
                name.to_string()
            }
            None => b.glsl.clone(),
        };
        names.push((generated, b.wgsl.clone()));
    }
    for (generated, wgsl) in &names {
        if !find_word(&text, wgsl).is_empty() {
            return Err(ShaderError::NameTaken { name: wgsl.clone() });
        }
        for at in find_word(&text, generated).into_iter().rev() {
            text.replace_range(at..at + generated.len(), wgsl);
        }
    }
    let files: Vec<&str> = program.files().iter().map(|(name, _)| *name).collect();
    let header = format!(
        "// Generated by `quatcurve shaders --library` (naga) from shaders/{}: the library's structs,\n\
         // uniforms and functions in GLSL ES 3.00, to put in a vertex shader of an engine's own.\n\
         // Uniforms by WGSL name: {}.\n",
        files.join(", "),
        names.iter().map(|(_, w)| w.as_str()).collect::<Vec<_>>().join(", ")
    );
    Ok(format!("{header}{}", text.trim_start()))
}

/// Where `word` occurs in `text` as a whole identifier.
fn find_word(text: &str, word: &str) -> Vec<usize> {
    let ident = |c: Option<char>| c.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
    text.match_indices(word)
        .map(|(at, _)| at)
        .filter(|&at| !ident(text[..at].chars().next_back()) && !ident(text[at + word.len()..].chars().next()))
        .collect()
}

/// One stage of a WGSL program in GLSL, with the names its resources took.
#[derive(Clone, Debug)]
pub struct Glsl {
    /// The GLSL source, `#version` first.
    pub text: String,
    /// Every bound resource, as the host binds it by name.
    pub bindings: Vec<GlslBinding>,
}

impl Glsl {
    /// The GLSL name of the vertex stage's input at `location`, when the text declares it
    /// (naga names an input from the pipeline `_p2vs_location{N}`; its reflection lists names
    /// only for GLSL versions without explicit locations).
    #[must_use]
    pub fn vertex_input(&self, location: u32) -> Option<String> {
        let name = format!("_p2vs_location{location}");
        self.text.contains(&format!("layout(location = {location}) in ")).then_some(())?;
        self.text.contains(&format!(" {name};")).then_some(name)
    }
}

/// A WGSL resource and the GLSL name naga gave it (GLSL has no bind groups).
#[derive(Clone, Debug)]
pub struct GlslBinding {
    /// The WGSL variable's name.
    pub wgsl: String,
    /// Its `@group` and `@binding`.
    pub group: u32,
    /// See [`Self::group`].
    pub binding: u32,
    /// The GLSL sampler's or uniform block's name.
    pub glsl: String,
    /// A texture (a `sampler2D`), else a uniform block.
    pub sampler: bool,
}

/// Entry point `entry` of the WGSL `files`, at `stage`, in GLSL 4.50 core or GLSL ES 3.00
/// (naga's back end, clip space as the API defines it: naga's default flips y and depth for
/// WebGPU's). Inter-stage values are named by location, so the vertex and fragment stages of
/// two programs link.
///
/// # Errors
/// naga's, in words; a `language` that is not GLSL.
pub fn glsl(
    files: &[(&str, &str)],
    entry: &str,
    stage: naga::ShaderStage,
    language: Language,
) -> Result<Glsl, ShaderError> {
    use naga::back::glsl;
    let version = match language {
        Language::Glsl => glsl::Version::Desktop(450),
        Language::GlslEs => glsl::Version::new_gles(300),
        other => return Err(ShaderError::NotGlsl { language: other }),
    };
    let (module, info) = validate(&join(files))?;
    let options = glsl::Options { version, writer_flags: glsl::WriterFlags::empty(), ..Default::default() };
    let pipeline = glsl::PipelineOptions { shader_stage: stage, entry_point: entry.to_string(), multiview: None };
    let mut text = String::new();
    let reflection =
        glsl::Writer::new(&mut text, &module, &info, &options, &pipeline, naga::proc::BoundsCheckPolicies::default())
            .and_then(|mut w| w.write())
            .map_err(ShaderError::Glsl)?;
    let binding = |h: naga::Handle<naga::GlobalVariable>, glsl: &str, sampler: bool| {
        let var = &module.global_variables[h];
        let (group, binding) = var.binding.as_ref().map_or((0, 0), |b| (b.group, b.binding));
        let wgsl = var.name.clone().unwrap_or_default();
        GlslBinding { wgsl, group, binding, glsl: glsl.to_string(), sampler }
    };
    let bindings = reflection
        .texture_mapping
        .iter()
        .map(|(glsl, m)| binding(m.texture, glsl, true))
        .chain(reflection.uniforms.iter().map(|(&h, glsl)| binding(h, glsl, false)))
        .collect();
    Ok(Glsl { text, bindings })
}

fn join(files: &[(&str, &str)]) -> String {
    files.iter().map(|(_, text)| *text).collect::<Vec<_>>().join("\n")
}

/// Parses and validates the program with naga.
///
/// # Errors
/// The parse or validation error, rendered with file context.
pub fn module() -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    validate(&source())
}

/// Parses and validates the forward-kinematics program with naga.
///
/// # Errors
/// As [`module`].
pub fn fk_module() -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    validate(&fk_source())
}

/// Parses and validates the playback program from resident curves with naga.
///
/// # Errors
/// naga's message when the program is invalid.
pub fn play_curves_module() -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    validate(&play_curves_source())
}

/// Parses and validates the playback program with naga.
///
/// # Errors
/// As [`module`].
pub fn play_module() -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    validate(&play_source())
}

/// Parses and validates the mesh-skinning program with naga.
///
/// # Errors
/// As [`module`].
pub fn skin_mesh_module() -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    validate(&skin_mesh_source())
}

/// Parses and validates the WGSL `files` as one module.
///
/// # Errors
/// As [`module`].
pub fn parse(files: &[(&str, &str)]) -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    validate(&join(files))
}

/// The size in bytes of struct `name` of `module` (a uniform block's, as the host fills it).
#[must_use]
pub fn struct_span(module: &naga::Module, name: &str) -> Option<u32> {
    module.types.iter().find_map(|(_, t)| match &t.inner {
        naga::TypeInner::Struct { span, .. } if t.name.as_deref() == Some(name) => Some(*span),
        _ => None,
    })
}

/// The `@location` inputs of entry point `entry`, by name (an argument's, or a member's of a
/// struct argument), so a host fills its vertex buffers by the names the shader uses.
///
/// # Errors
/// When the module has no such entry point.
pub fn vertex_inputs(module: &naga::Module, entry: &str) -> Result<Vec<(String, u32)>, ShaderError> {
    let ep = module
        .entry_points
        .iter()
        .find(|e| e.name == entry)
        .ok_or_else(|| ShaderError::NoEntryPoint { name: entry.into() })?;
    let mut inputs = Vec::new();
    for arg in &ep.function.arguments {
        match (&arg.binding, &module.types[arg.ty].inner) {
            (Some(naga::Binding::Location { location, .. }), _) => {
                inputs.push((arg.name.clone().unwrap_or_default(), *location));
            }
            (None, naga::TypeInner::Struct { members, .. }) => {
                for m in members {
                    if let Some(naga::Binding::Location { location, .. }) = &m.binding {
                        inputs.push((m.name.clone().unwrap_or_default(), *location));
                    }
                }
            }
            _ => {}
        }
    }
    Ok(inputs)
}

fn validate(src: &str) -> Result<(naga::Module, naga::valid::ModuleInfo), ShaderError> {
    let module =
        naga::front::wgsl::parse_str(src).map_err(|e| ShaderError::Wgsl { diagnostic: e.emit_to_string(src) })?;
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .map_err(|e| ShaderError::Wgsl { diagnostic: e.emit_to_string(src) })?;
    Ok((module, info))
}

/// The entry point's workgroup size (x), read from the parsed module so it is written once.
///
/// # Errors
/// When the entry point is missing or not one-dimensional.
pub fn workgroup_size(module: &naga::Module) -> Result<u32, ShaderError> {
    entry_workgroup_size(module, ENTRY_POINT)
}

/// The workgroup size (x) of entry point `name`.
///
/// # Errors
/// When the entry point is missing or not one-dimensional.
pub fn entry_workgroup_size(module: &naga::Module, name: &str) -> Result<u32, ShaderError> {
    let ep = module
        .entry_points
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| ShaderError::NoEntryPoint { name: name.into() })?;
    match ep.workgroup_size {
        [x, 1, 1] if x > 0 => Ok(x),
        other => Err(ShaderError::WorkgroupSize { size: other }),
    }
}

/// The bound variables entry point `name` uses, `(variable, binding)` by binding number: what a
/// pipeline built with an automatic layout (WebGPU's `layout: "auto"`) binds, no more.
///
/// # Errors
/// When the entry point is missing.
pub fn entry_point_bindings(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    name: &str,
) -> Result<Vec<(String, u32)>, ShaderError> {
    let index = module
        .entry_points
        .iter()
        .position(|e| e.name == name)
        .ok_or_else(|| ShaderError::NoEntryPoint { name: name.into() })?;
    let uses = info.get_entry_point(index);
    let mut bindings: Vec<(String, u32)> = module
        .global_variables
        .iter()
        .filter(|(handle, _)| !uses[*handle].is_empty())
        .filter_map(|(_, var)| Some((var.name.clone()?, var.binding.as_ref()?.binding)))
        .collect();
    bindings.sort_by_key(|&(_, b)| b);
    Ok(bindings)
}

/// A `u32` module-scope constant, by name (curve codes, limits).
#[must_use]
pub fn constant_u32(module: &naga::Module, name: &str) -> Option<u32> {
    let (_, c) = module.constants.iter().find(|(_, c)| c.name.as_deref() == Some(name))?;
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => Some(v),
        _ => None,
    }
}
