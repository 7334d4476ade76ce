//! Why the page cannot play a bake, or the server cannot start ([`ViewError`]): answered as
//! the request's 422 (or the command's failure), naming the file, clip or primitive.

use quatcurve_anim::error::InputError;
use quatcurve_bake::player::Unplayable;
use quatcurve_core::curve::UnknownName;
use quatcurve_gpu::GpuError;
use quatcurve_shader::ShaderError;

/// Why a bake cannot be played as the page plays it, or the viewer cannot serve.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ViewError {
    /// What is wrong inside one file of the bake.
    #[error("{file}: {error}")]
    InFile {
        /// The file, as the bake names it.
        file: String,
        /// What is wrong with it.
        error: Box<ViewError>,
    },
    /// A file that could not be read.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A sidecar that is not the sidecar's JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// An EXR texture its decoder refuses.
    #[error(transparent)]
    Exr(#[from] exr::error::Error),
    /// A PNG texture its decoder refuses.
    #[error(transparent)]
    Png(#[from] image::ImageError),
    /// A PNG texture that is not the 16-bit RGBA a png16 bake writes.
    #[error("a {color} PNG, not the 16-bit RGBA a png16 bake writes")]
    PngColor {
        /// Its colour type, as the decoder names it.
        color: String,
    },
    /// A mesh file the glTF crate refuses.
    #[error(transparent)]
    Gltf(#[from] gltf::Error),
    /// The baked glTF could not be read into the model, or its meshes broke a rule.
    #[error(transparent)]
    Input(#[from] InputError),
    /// A sidecar naming a curve, format or texture kind quatcurve does not have.
    #[error(transparent)]
    Name(#[from] UnknownName),
    /// A layout's std140 bytes that are not base64.
    #[error("its layout's `std140`: {0}")]
    Base64(#[from] base64::DecodeError),
    /// The shipped shaders could not be translated or reflected.
    #[error(transparent)]
    Shader(#[from] ShaderError),
    /// The curves cannot be laid out for the page's WebGPU.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A bake the page does not play, every reason named.
    #[error("{}; bake for player view", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    NotPlayable(Vec<Unplayable>),
    /// Something the bake or the shader should hold and does not.
    #[error("{what}")]
    Lacks {
        /// What is missing ("the sidecar names no baked glTF").
        what: &'static str,
    },
    /// A resource the vertex shader does not bind.
    #[error("the vertex shader binds no `{wgsl}`")]
    NoBinding {
        /// Its WGSL name.
        wgsl: String,
    },
    /// A vertex input the shader does not have.
    #[error("the vertex shader has no input `{name}`")]
    NoInput {
        /// The input.
        name: String,
    },
    /// A uniform struct the shader does not declare.
    #[error("no struct `{name}`")]
    NoStruct {
        /// The struct.
        name: String,
    },
    /// A uniform block packed to another size than its struct's.
    #[error("`{name}` is {span} bytes; {packed} were packed")]
    BlockSize {
        /// The struct.
        name: String,
        /// Its size.
        span: u32,
        /// The bytes packed.
        packed: usize,
    },
    /// A clip the bake does not have.
    #[error("no clip {clip}: the bake has {clips}")]
    NoClip {
        /// The clip asked for.
        clip: usize,
        /// The bake's clips.
        clips: usize,
    },
    /// A texture the sidecar's `textures` does not describe.
    #[error("the sidecar's `textures` has no record of {file}")]
    NoTextureRecord {
        /// The texture file.
        file: String,
    },
    /// A texture record without its layout uniform.
    #[error("its `textures` record has no `layout` (an older quatcurve wrote it: bake it again)")]
    NoLayout,
    /// A layout that does not hold the clip played.
    #[error("its layout does not hold clip {clip} (it holds clips {held:?})")]
    ClipNotInLayout {
        /// The clip played.
        clip: usize,
        /// The clips it holds.
        held: Vec<usize>,
    },
    /// A clip at different places in two textures' layouts (one instance attribute gives it).
    #[error("clip {clip} is at {at} of its layout, at {other} of another's")]
    ClipPlaces {
        /// The clip played.
        clip: usize,
        /// Its index in this layout.
        at: usize,
        /// Its index in another's.
        other: usize,
    },
    /// Layout bytes that are not whole 32-bit words.
    #[error("its layout's `std140` is {bytes} bytes, not whole words")]
    Std140Words {
        /// The bytes.
        bytes: usize,
    },
    /// A texture record without the box a vertex texture's positions decode in.
    #[error("its `textures` record has no `low` and `span`")]
    NoBox,
    /// A PNG16 texture's remap of fewer texel slots than a joint takes.
    #[error("`remap` has {slots} texel slots, not {expected}")]
    RemapSlots {
        /// The slots given.
        slots: usize,
        /// The slots a joint takes.
        expected: usize,
    },
    /// A skinned primitive whose skin has no texture in the clip.
    #[error("{primitive}: no texture of skin {skin}")]
    NoSkinTexture {
        /// The primitive.
        primitive: String,
        /// Its skin.
        skin: usize,
    },
    /// A texel the grid puts outside its image.
    #[error("{primitive}: texel ({x}, {y}) is outside its {width}x{height} image")]
    TexelOutside {
        /// The primitive drawn.
        primitive: String,
        /// The texel's column.
        x: usize,
        /// The texel's row.
        y: usize,
        /// The image's width.
        width: usize,
        /// The image's height.
        height: usize,
    },
    /// A vertex primitive whose positions the clip does not list.
    #[error("{primitive}: the clip lists no {file}")]
    NoPositions {
        /// The primitive.
        primitive: String,
        /// The file it needs.
        file: String,
    },
    /// A mesh the mesh file does not have.
    #[error("no mesh {mesh}")]
    NoMesh {
        /// The mesh index.
        mesh: usize,
    },
    /// A baked glTF whose clips are not the bake's.
    #[error("its clips {curves:?} are not the bake's {baked:?}")]
    ClipsDiffer {
        /// The baked glTF's clips.
        curves: Vec<String>,
        /// The sidecar's.
        baked: Vec<String>,
    },
    /// More instances than one frame plays, or none.
    #[error("{instances} instances: one frame plays 1 to {max} of this character")]
    Instances {
        /// Instances asked for.
        instances: usize,
        /// The most one frame plays.
        max: usize,
    },
    /// An address the server cannot listen on.
    #[error("{address}: {reason}")]
    Bind {
        /// The address asked for.
        address: String,
        /// The system's reason.
        reason: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A listening address that is not an IP address.
    #[error("{address} is not an IP address")]
    NotIp {
        /// The address.
        address: String,
    },
}

impl ViewError {
    /// This error inside `file` (`.map_err(ViewError::in_file(name))`).
    pub fn in_file(file: impl std::fmt::Display) -> impl FnOnce(Self) -> Self {
        let file = file.to_string();
        move |error| Self::InFile { file, error: Box::new(error) }
    }
}
